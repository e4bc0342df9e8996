//! Eight f32 lanes, written once and compiled three ways: for AVX2 (`Avx2`,
//! one 256-bit register), for any x86-64 CPU (`Sse2`, two 128-bit
//! registers) and for any CPU ([`Scalar`], an array the compiler may or may
//! not vectorise). Code generic over [`F32x8`] runs through [`with_lanes`],
//! which picks the kind once per process ([`Lanes::best`]).
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
use std::sync::OnceLock;

use glam::Vec3;

#[cfg(target_arch = "x86_64")]
use super::{Simd, simd_level};

/// Eight f32 lanes: the kinds of this module, and no others (the trait is
/// sealed, so that every kind keeps the promise of bitwise the same
/// results).
pub trait F32x8:
    sealed::Sealed
    + Copy
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
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
    /// Per lane `self > 0 ? value : +0` (a NaN in `self` gives +0).
    fn where_positive(self, value: Self) -> Self;
    /// Per lane `self <= limit ? value : +0` (a NaN on either side gives +0).
    fn where_le(self, limit: Self, value: Self) -> Self;
    /// Bit l set where lane l has `self <= limit` (a NaN on either side
    /// gives 0).
    fn le_bits(self, limit: Self) -> u32;

    /// How many of the first `lanes` lanes (at most 8) have
    /// `self <= limit` (a NaN on either side does not count).
    #[inline(always)]
    fn count_le(self, limit: Self, lanes: usize) -> u32 {
        (self.le_bits(limit) & first_bits(lanes)).count_ones()
    }

    /// Writes `base + l` for each of the first `lanes` lanes l (at most 8)
    /// with `self <= limit`, in increasing order, to the front of `out`,
    /// and returns how many: the hits of a distance test, packed. The
    /// other entries of `out[..8]` may be overwritten.
    ///
    /// # Panics
    /// If `out` holds fewer than 8 entries.
    #[inline(always)]
    fn pack_le(self, limit: Self, lanes: usize, base: u32, out: &mut [u32]) -> usize {
        let bits = self.le_bits(limit) & first_bits(lanes);
        let out = &mut out[..8];
        let mut n = 0;
        // Each lane writes its slot and advances the count by its bit: no
        // branch per hit.
        for l in 0..8u32 {
            // Wrapping, as the AVX2 kind's integer add (a slot within 7 of
            // u32::MAX is allowed; its lanes past the hits are ignored).
            out[n] = base.wrapping_add(l);
            n += ((bits >> l) & 1) as usize;
        }
        n
    }
    /// 1 in the first `count` lanes, 0 in the others.
    fn first(count: usize) -> Self;
    /// Four lane sets from eight rows of four floats, lane l of set k
    /// getting `row(l)[k]`: what the gathers below are made of.
    fn transpose<'a>(row: impl Fn(usize) -> &'a [f32; 4]) -> [Self; 4];

    /// Eight lane sets from eight rows of eight floats, lane l of set k
    /// getting `row(l)[k]`: two 4 × 4 transposes unless a kind has a better
    /// way. `row` is called once per lane, in lane order.
    #[inline(always)]
    fn transpose8<'a>(row: impl Fn(usize) -> &'a [f32; 8]) -> [Self; 8] {
        let rows = [
            row(0),
            row(1),
            row(2),
            row(3),
            row(4),
            row(5),
            row(6),
            row(7),
        ];
        let [a, b, c, d] = Self::transpose(|l| first_four(rows[l]));
        let [e, f, g, h] = Self::transpose(|l| first_four(&rows[l][4..]));
        [a, b, c, d, e, f, g, h]
    }

    /// Eight lane sets, lane l of set k getting `rows[slots[l]][k]`.
    ///
    /// # Panics
    /// If a slot is out of bounds.
    #[inline(always)]
    fn gather_rows8(rows: &[[f32; 8]], slots: &[u32; 8]) -> [Self; 8] {
        Self::transpose8(|l| &rows[slots[l] as usize])
    }

    /// Lanes from `values[at..at + 8]`.
    ///
    /// # Panics
    /// If `values` holds fewer than `at + 8` floats.
    #[inline(always)]
    fn load(values: &[f32], at: usize) -> Self {
        let mut a = [0.0; 8];
        a.copy_from_slice(&values[at..at + 8]);
        Self::from_array(a)
    }

    /// Lanes from the eight floats at `values`, without a bounds check:
    /// for loops whose bounds are checked once outside them (the neighbour
    /// scan's padded rows).
    ///
    /// # Safety
    /// `values` must be valid for reading eight floats.
    #[inline(always)]
    unsafe fn load_unchecked(values: *const f32) -> Self {
        // SAFETY: the caller's promise.
        let a = unsafe { values.cast::<[f32; 8]>().read_unaligned() };
        Self::from_array(a)
    }

    /// The first `count` lanes (all eight if `count` ≥ 8) from
    /// `values[at..]`, the others `fill`'s: the last chunk of a run of
    /// values, read without touching anything past its end.
    ///
    /// # Panics
    /// If `values` holds fewer than `at + min(count, 8)` floats.
    #[inline(always)]
    fn load_first(values: &[f32], at: usize, count: usize, fill: Self) -> Self {
        let mut a = fill.to_array();
        let n = count.min(8);
        a[..n].copy_from_slice(&values[at..at + n]);
        Self::from_array(a)
    }

    /// Lanes `8 half .. 8 half + 8` of sixteen (`half` 0 or 1): a
    /// 16-lane sum kept as two kinds' halves.
    ///
    /// # Panics
    /// If `half` > 1.
    #[inline(always)]
    fn half(lanes: &[f32; 16], half: usize) -> Self {
        Self::load(lanes, 8 * half)
    }

    /// Writes the lanes to `lanes[8 half .. 8 half + 8]`: [`F32x8::half`]
    /// the other way.
    ///
    /// # Panics
    /// If `half` > 1.
    #[inline(always)]
    fn store_half(self, lanes: &mut [f32; 16], half: usize) {
        lanes[8 * half..8 * half + 8].copy_from_slice(&self.to_array());
    }

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

/// Only this module's kinds implement [`F32x8`].
mod sealed {
    pub trait Sealed {}
    impl Sealed for super::Scalar {}
    #[cfg(target_arch = "x86_64")]
    impl Sealed for super::Avx2 {}
    #[cfg(target_arch = "x86_64")]
    impl Sealed for super::Sse2 {}
}

/// Bits 0 to `lanes` − 1 set (all eight if `lanes` ≥ 8).
#[inline(always)]
fn first_bits(lanes: usize) -> u32 {
    (1u32 << lanes.min(8)) - 1
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
/// reference the tests hold the other kinds to ([`Lanes::every`]'s first).
#[derive(Debug, Clone, Copy)]
pub struct Scalar([f32; 8]);

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
    fn where_positive(self, value: Self) -> Self {
        Scalar(std::array::from_fn(|l| {
            if self.0[l] > 0.0 { value.0[l] } else { 0.0 }
        }))
    }
    #[inline(always)]
    fn where_le(self, limit: Self, value: Self) -> Self {
        Scalar(std::array::from_fn(|l| {
            if self.0[l] <= limit.0[l] {
                value.0[l]
            } else {
                0.0
            }
        }))
    }
    #[inline(always)]
    fn le_bits(self, limit: Self) -> u32 {
        let mut bits = 0;
        for l in 0..8 {
            bits |= u32::from(self.0[l] <= limit.0[l]) << l;
        }
        bits
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

    /// Eight lanes in one AVX2 register, made only on a CPU with AVX2
    /// (under [`super::Lanes::run`]'s dispatch).
    #[derive(Debug, Clone, Copy)]
    pub(in crate::simd) struct Avx2(__m256);

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

    /// For each 8-lane mask, the lanes of its set bits in increasing order,
    /// one per byte from the lowest (the rest 0): [`F32x8::pack_le`]'s
    /// permutation.
    // A constant reference, not a `static`: a generic caller instantiated in
    // another crate reached a `static` through the GOT on every chunk; the
    // promoted table is local to each crate, and is not copied per use.
    const PACK: &[u64; 256] = &{
        let mut table = [0u64; 256];
        let mut mask = 0;
        while mask < 256 {
            let (mut lane, mut n) = (0, 0);
            while lane < 8 {
                if mask & (1 << lane) != 0 {
                    table[mask] |= (lane as u64) << (8 * n);
                    n += 1;
                }
                lane += 1;
            }
            mask += 1;
        }
        table
    };

    // SAFETY (every `unsafe` block below): an `Avx2` is made only on a CPU
    // with AVX2. The type is private to the `simd` module, and the only
    // code that names it is `call_avx2` and `call_avx512vl` (`unsafe fn`s
    // that `Lanes::run` calls only for a `Lanes` made after checking the
    // CPU for AVX2, or for AVX-512VL with `wide_registers`), so the
    // functions that make one from nothing (`splat`, `from_array`, `first`,
    // `transpose`, `transpose8`, `load`, `load_unchecked`, `load_first`)
    // run only on such a CPU, whether or not the code around them was
    // compiled for it. The loads read whole `[f32; 4]`s, `[f32; 8]`s and
    // arrays of eight, slices checked to hold eight floats, or (masked) the
    // first `count` of a slice checked to hold them; `load_unchecked` reads
    // the eight floats its caller promises.
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
        fn where_positive(self, value: Self) -> Self {
            // All ones where self > 0 (ordered: false for NaN), then the
            // value's bits or +0.
            unsafe {
                let positive = _mm256_cmp_ps::<_CMP_GT_OQ>(self.0, _mm256_setzero_ps());
                Avx2(_mm256_and_ps(positive, value.0))
            }
        }
        #[inline(always)]
        fn where_le(self, limit: Self, value: Self) -> Self {
            // All ones where self <= limit (ordered: false for NaN).
            unsafe {
                let le = _mm256_cmp_ps::<_CMP_LE_OQ>(self.0, limit.0);
                Avx2(_mm256_and_ps(le, value.0))
            }
        }
        #[inline(always)]
        fn le_bits(self, limit: Self) -> u32 {
            unsafe { _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(self.0, limit.0)) as u32 }
        }
        #[inline(always)]
        fn pack_le(self, limit: Self, lanes: usize, base: u32, out: &mut [u32]) -> usize {
            let bits = self.le_bits(limit) & super::first_bits(lanes);
            let out = &mut out[..8];
            // The hit lanes, packed to the front by a permutation looked up
            // by the mask, plus `base`, stored whole.
            unsafe {
                let order = _mm256_cvtepu8_epi32(_mm_cvtsi64_si128(PACK[bits as usize] as i64));
                let slots = _mm256_add_epi32(_mm256_set1_epi32(base as i32), order);
                _mm256_storeu_si256(out.as_mut_ptr().cast(), slots);
            }
            bits.count_ones() as usize
        }
        #[inline(always)]
        fn load(values: &[f32], at: usize) -> Self {
            let v = &values[at..at + 8];
            Avx2(unsafe { _mm256_loadu_ps(v.as_ptr()) })
        }
        #[inline(always)]
        unsafe fn load_unchecked(values: *const f32) -> Self {
            // SAFETY: the caller's promise.
            Avx2(unsafe { _mm256_loadu_ps(values) })
        }
        #[inline(always)]
        fn load_first(values: &[f32], at: usize, count: usize, fill: Self) -> Self {
            if count >= 8 {
                return Self::load(values, at);
            }
            let v = &values[at..at + count];
            // The masked load reads only the first `count` lanes, which
            // `v` holds; a blend puts `fill` in the others.
            unsafe {
                let lane = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
                let mask = _mm256_cmpgt_epi32(_mm256_set1_epi32(count as i32), lane);
                let loaded = _mm256_maskload_ps(v.as_ptr(), mask);
                Avx2(_mm256_blendv_ps(fill.0, loaded, _mm256_castsi256_ps(mask)))
            }
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
        #[inline(always)]
        fn transpose8<'a>(row: impl Fn(usize) -> &'a [f32; 8]) -> [Self; 8] {
            // SAFETY: each row holds eight floats.
            let rows = [
                row(0),
                row(1),
                row(2),
                row(3),
                row(4),
                row(5),
                row(6),
                row(7),
            ];
            // Loads written out, not in a closure (see `LaneFn`).
            let r = unsafe {
                [
                    _mm256_loadu_ps(rows[0].as_ptr()),
                    _mm256_loadu_ps(rows[1].as_ptr()),
                    _mm256_loadu_ps(rows[2].as_ptr()),
                    _mm256_loadu_ps(rows[3].as_ptr()),
                    _mm256_loadu_ps(rows[4].as_ptr()),
                    _mm256_loadu_ps(rows[5].as_ptr()),
                    _mm256_loadu_ps(rows[6].as_ptr()),
                    _mm256_loadu_ps(rows[7].as_ptr()),
                ]
            };
            // Unpack pairs of rows, shuffle quadruples, then swap 128-bit
            // halves.
            unsafe {
                let t0 = _mm256_unpacklo_ps(r[0], r[1]);
                let t1 = _mm256_unpackhi_ps(r[0], r[1]);
                let t2 = _mm256_unpacklo_ps(r[2], r[3]);
                let t3 = _mm256_unpackhi_ps(r[2], r[3]);
                let t4 = _mm256_unpacklo_ps(r[4], r[5]);
                let t5 = _mm256_unpackhi_ps(r[4], r[5]);
                let t6 = _mm256_unpacklo_ps(r[6], r[7]);
                let t7 = _mm256_unpackhi_ps(r[6], r[7]);
                let s0 = _mm256_shuffle_ps::<0x44>(t0, t2);
                let s1 = _mm256_shuffle_ps::<0xEE>(t0, t2);
                let s2 = _mm256_shuffle_ps::<0x44>(t1, t3);
                let s3 = _mm256_shuffle_ps::<0xEE>(t1, t3);
                let s4 = _mm256_shuffle_ps::<0x44>(t4, t6);
                let s5 = _mm256_shuffle_ps::<0xEE>(t4, t6);
                let s6 = _mm256_shuffle_ps::<0x44>(t5, t7);
                let s7 = _mm256_shuffle_ps::<0xEE>(t5, t7);
                [
                    Avx2(_mm256_permute2f128_ps::<0x20>(s0, s4)),
                    Avx2(_mm256_permute2f128_ps::<0x20>(s1, s5)),
                    Avx2(_mm256_permute2f128_ps::<0x20>(s2, s6)),
                    Avx2(_mm256_permute2f128_ps::<0x20>(s3, s7)),
                    Avx2(_mm256_permute2f128_ps::<0x31>(s0, s4)),
                    Avx2(_mm256_permute2f128_ps::<0x31>(s1, s5)),
                    Avx2(_mm256_permute2f128_ps::<0x31>(s2, s6)),
                    Avx2(_mm256_permute2f128_ps::<0x31>(s3, s7)),
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
    pub(in crate::simd) struct Sse2([__m128; 2]);

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
        fn where_positive(self, value: Self) -> Self {
            let [a, b] = self.0;
            let [c, d] = value.0;
            unsafe {
                let zero = _mm_setzero_ps();
                Sse2([
                    _mm_and_ps(_mm_cmpgt_ps(a, zero), c),
                    _mm_and_ps(_mm_cmpgt_ps(b, zero), d),
                ])
            }
        }
        #[inline(always)]
        fn where_le(self, limit: Self, value: Self) -> Self {
            let [a, b] = self.0;
            let [c, d] = limit.0;
            let [e, f] = value.0;
            unsafe {
                Sse2([
                    _mm_and_ps(_mm_cmple_ps(a, c), e),
                    _mm_and_ps(_mm_cmple_ps(b, d), f),
                ])
            }
        }
        #[inline(always)]
        fn le_bits(self, limit: Self) -> u32 {
            let [a, b] = self.0;
            let [c, d] = limit.0;
            let le = unsafe {
                _mm_movemask_ps(_mm_cmple_ps(a, c)) | (_mm_movemask_ps(_mm_cmple_ps(b, d)) << 4)
            };
            le as u32
        }
        #[inline(always)]
        fn load(values: &[f32], at: usize) -> Self {
            let v = &values[at..at + 8];
            unsafe { Sse2([_mm_loadu_ps(v.as_ptr()), _mm_loadu_ps(v.as_ptr().add(4))]) }
        }
        #[inline(always)]
        unsafe fn load_unchecked(values: *const f32) -> Self {
            // SAFETY: the caller's promise.
            unsafe { Sse2([_mm_loadu_ps(values), _mm_loadu_ps(values.add(4))]) }
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

/// A computation written once over lanes of any kind: [`with_lanes`] runs
/// it with the best kind this CPU has, [`Lanes::every`] with each kind in
/// turn.
///
/// `call` must be `#[inline(always)]`, and so must whatever it calls with
/// the lanes: the kinds are compiled for their instructions only where
/// they are inlined into the dispatch's `#[target_feature]` functions.
/// Outside them each lane operation would be a function call. Closures
/// (`array::map`, a callback) are compiled on their own, so the lanes
/// should not be used inside one unless it is inlined for certain: write
/// loops, and dispatch inside a callback rather than around it.
pub trait LaneFn {
    /// What the computation gives.
    type Out;
    /// The computation with lanes `S`.
    fn call<S: F32x8>(self) -> Self::Out;
}

/// Which kind of lanes: private, so that a [`Lanes`] can only name a kind
/// this CPU runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    /// [`Scalar`]: arrays, for any CPU.
    Plain,
    /// `Sse2`: two 128-bit registers, for any x86-64 CPU.
    #[cfg(target_arch = "x86_64")]
    Sse2,
    /// `Avx2`: one 256-bit register.
    #[cfg(target_arch = "x86_64")]
    Avx2,
    /// `Avx2` compiled with AVX-512VL's 32 registers ([`wide_registers`]).
    #[cfg(target_arch = "x86_64")]
    Avx2Wide,
}

/// A kind of eight f32 lanes this CPU runs: [`Lanes::best`], or one of
/// [`Lanes::every`]. Every kind gives bitwise the same results; they differ
/// only in speed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Lanes(Kind);

impl Lanes {
    /// The lanes [`with_lanes`] uses: AVX2 where [`simd_level`] allows it
    /// (compiled with AVX-512VL's registers where the CPU has them), else
    /// SSE2 on x86-64 (`SPH_SIMD=baseline` included), else plain arrays.
    /// Chosen once per process.
    #[inline]
    pub fn best() -> Lanes {
        static BEST: OnceLock<Lanes> = OnceLock::new();
        *BEST.get_or_init(|| {
            #[cfg(target_arch = "x86_64")]
            {
                if wide_registers() {
                    return Lanes(Kind::Avx2Wide);
                }
                if simd_level() >= Simd::Avx2 {
                    return Lanes(Kind::Avx2);
                }
                Lanes(Kind::Sse2)
            }
            #[cfg(not(target_arch = "x86_64"))]
            Lanes(Kind::Plain)
        })
    }

    /// Every kind this CPU runs, whatever `SPH_SIMD` says, the plain arrays
    /// first: what tests run a computation with to compare the kinds.
    pub fn every() -> Vec<Lanes> {
        #[allow(unused_mut)]
        let mut kinds = vec![Lanes(Kind::Plain)];
        #[cfg(target_arch = "x86_64")]
        {
            kinds.push(Lanes(Kind::Sse2));
            if Simd::detect() >= Simd::Avx2 {
                kinds.push(Lanes(Kind::Avx2));
            }
            if wide_cpu() {
                kinds.push(Lanes(Kind::Avx2Wide));
            }
        }
        kinds
    }

    /// The kind's name: `plain`, `sse2`, `avx2` or `avx2+avx512vl`. At
    /// `SPH_SIMD=baseline` (the [`Simd::Baseline`] level) the best kind is
    /// `sse2` on x86-64 and `plain` elsewhere; at `avx2` it is `avx2`; at
    /// `avx512` `avx2+avx512vl` where the CPU has AVX-512VL.
    pub fn name(self) -> &'static str {
        match self.0 {
            Kind::Plain => "plain",
            #[cfg(target_arch = "x86_64")]
            Kind::Sse2 => "sse2",
            #[cfg(target_arch = "x86_64")]
            Kind::Avx2 => "avx2",
            #[cfg(target_arch = "x86_64")]
            Kind::Avx2Wide => "avx2+avx512vl",
        }
    }

    /// Runs `f` with these lanes. `f`'s `call` must be `#[inline(always)]`
    /// (see [`LaneFn`]).
    #[inline]
    pub fn run<F: LaneFn>(self, f: F) -> F::Out {
        match self.0 {
            Kind::Plain => call_plain(f),
            #[cfg(target_arch = "x86_64")]
            Kind::Sse2 => call_sse2(f),
            // SAFETY: a `Lanes` names AVX2 only where the CPU has it, and
            // POPCNT with it (`best` and `every` check `Simd`'s levels,
            // which require both, and nothing else makes one).
            #[cfg(target_arch = "x86_64")]
            Kind::Avx2 => unsafe { call_avx2(f) },
            // SAFETY: as above, checked by `wide_registers`.
            #[cfg(target_arch = "x86_64")]
            Kind::Avx2Wide => unsafe { call_avx512vl(f) },
        }
    }
}

/// Runs `f` with [`Lanes::best`].
#[inline]
pub fn with_lanes<F: LaneFn>(f: F) -> F::Out {
    Lanes::best().run(f)
}

/// [`LaneFn::call`] with the plain lanes. Not inlined, as the AVX2 kinds'
/// `#[target_feature]` functions cannot be: a dispatch inlined into its
/// caller then costs a call whatever the kind, and does not copy every
/// kind's loop into the caller (whose own loop then ran 9 % more
/// instructions around the neighbour scan).
#[inline(never)]
fn call_plain<F: LaneFn>(f: F) -> F::Out {
    f.call::<Scalar>()
}

/// [`LaneFn::call`] with the SSE2 lanes, not inlined (see [`call_plain`]).
#[cfg(target_arch = "x86_64")]
#[inline(never)]
fn call_sse2<F: LaneFn>(f: F) -> F::Out {
    f.call::<Sse2>()
}

/// [`LaneFn::call`] with the AVX2 lanes, compiled with AVX2.
///
/// # Safety
/// The CPU must support AVX2 and POPCNT (which the AVX2 level requires).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,popcnt")]
unsafe fn call_avx2<F: LaneFn>(f: F) -> F::Out {
    f.call::<Avx2>()
}

/// [`LaneFn::call`] with the AVX2 lanes, compiled with AVX-512VL as well
/// (see [`wide_registers`]).
///
/// # Safety
/// The CPU must support AVX2, AVX-512F, AVX-512VL, POPCNT, FMA and F16C
/// (which AVX-512F implies to the compiler).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,avx512f,avx512vl,popcnt")]
unsafe fn call_avx512vl<F: LaneFn>(f: F) -> F::Out {
    f.call::<Avx2>()
}

/// Whether to compile the AVX2 lanes' code with AVX-512VL too: the same
/// 8-lane instructions, but with 32 vector registers instead of 16, so the
/// sums of a pass stay in registers instead of spilling to the stack
/// (AVX-512's own 16-lane registers were slower on Zen 4, which splits
/// them in two). The results are bitwise the same: the compiler may encode
/// an operation differently, not change it.
#[cfg(target_arch = "x86_64")]
fn wide_registers() -> bool {
    simd_level() >= Simd::Avx512 && wide_cpu()
}

/// Whether this CPU, whatever `SPH_SIMD` says, has what
/// [`wide_registers`]' code is compiled for.
#[cfg(target_arch = "x86_64")]
fn wide_cpu() -> bool {
    use std::arch::is_x86_feature_detected as has;
    // AVX-512F implies FMA and F16C to the compiler: a VM could hide them
    // (`Simd::detect` checks them for the AVX-512 level too).
    Simd::detect() >= Simd::Avx512 && has!("avx512vl") && has!("fma") && has!("f16c")
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every lane operation, on fixed inputs.
    #[derive(Clone, Copy)]
    struct Ops<'a> {
        a: [f32; 8],
        b: [f32; 8],
        rows: &'a [[f32; 4]],
        rows8: &'a [[f32; 8]],
        values: &'a [f32],
        slots: &'a [u32; 8],
    }

    impl LaneFn for Ops<'_> {
        type Out = Vec<[f32; 8]>;
        #[inline(always)]
        fn call<S: F32x8>(self) -> Vec<[f32; 8]> {
            let (a, b, slots) = (S::from_array(self.a), S::from_array(self.b), self.slots);
            let mut out = vec![
                (a + b).to_array(),
                (a - b).to_array(),
                (a * b).to_array(),
                (a / b).to_array(),
                a.max(b).to_array(),
                b.max(a).to_array(),
                a.sqrt().to_array(),
                S::gather(self.values, slots).to_array(),
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
            out.extend(S::gather_rows(self.rows, slots).map(S::to_array));
            let v: Vec<Vec3> = self
                .rows
                .iter()
                .map(|r| Vec3::new(r[0], r[1], r[2]))
                .collect();
            out.extend(S::load_vec3s(&v[5..]).map(S::to_array));
            out.extend(S::gather_rows8(self.rows8, slots).map(S::to_array));
            out.push(a.where_positive(b).to_array());
            out.push(b.where_positive(a).to_array());
            let sixteen: [f32; 16] = std::array::from_fn(|l| l as f32 * 0.25);
            out.push(S::half(&sixteen, 1).to_array());
            out.push(a.where_le(b, S::splat(4.0)).to_array());
            out.push(b.where_le(a, a).to_array());
            let counts = [0, 1, 5, 8, 9].map(|n| a.count_le(b, n) as f32);
            out.push([
                counts[0], counts[1], counts[2], counts[3], counts[4], 0.0, 0.0, 0.0,
            ]);
            out.push(S::load(self.values, 3).to_array());
            // SAFETY: values[5..13] exist (20 values).
            out.push(unsafe { S::load_unchecked(self.values.as_ptr().add(5)) }.to_array());
            let fill = S::splat(-1.0);
            out.push(S::load_first(self.values, 17, 3, fill).to_array());
            out.push(S::load_first(self.values, 12, 8, fill).to_array());
            out.push(S::load_first(self.values, 20, 0, fill).to_array());
            let mut packed = [u32::MAX; 8];
            let hits = b.pack_le(a, 8, 100, &mut packed);
            out.push(std::array::from_fn(|l| {
                if l < hits { packed[l] as f32 } else { -1.0 }
            }));
            let hits = b.pack_le(a, 5, 7, &mut packed);
            out.push(std::array::from_fn(|l| {
                if l < hits { packed[l] as f32 } else { -1.0 }
            }));
            out.push([
                a.le_bits(b) as f32,
                b.le_bits(a) as f32,
                0.0,
                0.0,
                0.0,
                0.0,
                0.0,
                0.0,
            ]);
            out
        }
    }

    /// Every kind this CPU runs gives bitwise the same lanes for each
    /// operation, signed zeros, NaNs and infinities in `max` included.
    #[test]
    fn every_kind_agrees_bit_for_bit() {
        let rows: Vec<[f32; 4]> = (0..20)
            .map(|i| std::array::from_fn(|k| i as f32 * 0.37 + k as f32))
            .collect();
        let rows8: Vec<[f32; 8]> = (0..20)
            .map(|i| std::array::from_fn(|k| i as f32 * 0.53 - k as f32))
            .collect();
        let values: Vec<f32> = (0..20).map(|i| i as f32 * 1.1).collect();
        let ops = Ops {
            a: [1.5, -0.0, 0.0, f32::NAN, 3.0, -2.0, f32::INFINITY, 1e-30],
            b: [0.25, 0.0, -0.0, 1.0, f32::NAN, 7.0, 2.0, 3e-38],
            rows: &rows,
            rows8: &rows8,
            values: &values,
            slots: &[3, 19, 0, 7, 7, 12, 5, 1],
        };
        // Bits, with every NaN one pattern: a NaN's sign and payload are
        // not results (the compiler folds 0/0 to a different one than the
        // CPU makes).
        let bits = |v: Vec<[f32; 8]>| -> Vec<[u32; 8]> {
            let bits = |x: f32| if x.is_nan() { u32::MAX } else { x.to_bits() };
            v.into_iter().map(|l| l.map(bits)).collect()
        };
        let kinds = Lanes::every();
        assert_eq!(kinds[0].name(), "plain");
        #[cfg(target_arch = "x86_64")]
        assert!(kinds.len() >= 2, "SSE2 on every x86-64 CPU");
        assert!(kinds.contains(&Lanes::best()));
        let plain = kinds[0].run(ops);
        assert_eq!(plain[4][0], 1.5);
        assert_eq!(
            plain[4][1].to_bits(),
            0.0f32.to_bits(),
            "max(-0, +0) is the second"
        );
        assert!(plain[4][4].is_nan(), "max(3, NaN) is the second");
        assert_eq!(plain[4][3], 1.0, "max(NaN, 1) is the second");
        assert_eq!(plain[8], [1.0, 1.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
        assert_eq!(plain[9], [1.0; 8]);
        assert_eq!(plain[12][1], 19.0 * 0.37, "gathered row 19, first entry");
        assert_eq!(plain[16][0], 5.0 * 0.37, "vector 5's x in lane 0");
        assert_eq!(plain[18][7], 12.0 * 0.37 + 2.0, "vector 12's z in lane 7");
        assert_eq!(plain[15][0], 3.0 * 0.37 + 3.0, "gathered row 3, last entry");
        assert_eq!(plain[19][1], 19.0 * 0.53, "gathered 8-row 19, entry 0");
        assert_eq!(plain[26][0], 3.0 * 0.53 - 7.0, "gathered 8-row 3, entry 7");
        assert_eq!(plain[23][7], 1.0 * 0.53 - 4.0, "gathered 8-row 1, entry 4");
        // a = [1.5, -0, 0, NaN, 3, -2, inf, 1e-30], b = [0.25, 0, -0, 1, NaN, 7, 2, 3e-38].
        assert!(plain[27][4].is_nan(), "3 > 0: b's NaN");
        let mut positive = plain[27];
        positive[4] = 9.0;
        assert_eq!(positive, [0.25, 0.0, 0.0, 0.0, 9.0, 0.0, 2.0, 3e-38]);
        assert_eq!(plain[27][1].to_bits(), 0, "−0 is not positive: +0");
        assert!(plain[28][3].is_nan(), "1 > 0: a's NaN");
        let mut positive = plain[28];
        positive[3] = 9.0;
        assert_eq!(
            positive,
            [1.5, 0.0, 0.0, 9.0, 0.0, -2.0, f32::INFINITY, 1e-30]
        );
        assert_eq!(plain[29], [2.0, 2.25, 2.5, 2.75, 3.0, 3.25, 3.5, 3.75]);
        // a <= b: 1.5 no, −0 <= 0, 0 <= −0, NaN no, 3 <= NaN no, −2 <= 7,
        // inf no, 1e-30 no.
        assert_eq!(plain[30], [0.0, 4.0, 4.0, 0.0, 0.0, 4.0, 0.0, 0.0]);
        assert_eq!(plain[31][0], 1.5, "0.25 <= 1.5: a's lane");
        assert_eq!(plain[31][4], 0.0, "NaN <= 3 is false");
        assert_eq!(plain[31][7], 1e-30, "3e-38 <= 1e-30");
        assert_eq!(plain[32][..5], [0.0, 0.0, 2.0, 3.0, 3.0]);
        assert_eq!(plain[33], std::array::from_fn(|l| (3 + l) as f32 * 1.1));
        assert_eq!(plain[34], std::array::from_fn(|l| (5 + l) as f32 * 1.1));
        assert_eq!(
            plain[35],
            [
                17.0 * 1.1,
                18.0 * 1.1,
                19.0 * 1.1,
                -1.0,
                -1.0,
                -1.0,
                -1.0,
                -1.0
            ]
        );
        assert_eq!(plain[36], std::array::from_fn(|l| (12 + l) as f32 * 1.1));
        assert_eq!(plain[37], [-1.0; 8], "none loaded past the end");
        // b <= a: 0.25 <= 1.5, 0 <= −0, −0 <= 0, 1 vs NaN no, NaN no,
        // 7 <= −2 no, 2 <= inf, 3e-38 <= 1e-30.
        assert_eq!(
            plain[38],
            [100.0, 101.0, 102.0, 106.0, 107.0, -1.0, -1.0, -1.0]
        );
        assert_eq!(plain[39], [7.0, 8.0, 9.0, -1.0, -1.0, -1.0, -1.0, -1.0]);
        assert_eq!(plain[40][..2], [0b0010_0110 as f32, 0b1100_0111 as f32]);
        let plain = bits(plain);
        for kind in &kinds[1..] {
            assert_eq!(bits(kind.run(ops)), plain, "{}", kind.name());
        }
    }
}
