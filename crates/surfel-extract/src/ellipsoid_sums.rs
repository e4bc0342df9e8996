//! The anisotropic field's sums at a point: c, ∇c, ∇²c of the ellipsoidal
//! kernels det G · W_poly6(|G r|) over the kernels within h, eight at a time.
//!
//! The grid's scan hands over the neighbours one by one; they are buffered
//! eight at a time (hit m in lane m mod 8) with their offsets, and each full
//! buffer is summed lane by lane: the eight kernels are loaded as whole rows
//! of 8 floats and transposed in registers (AVX2), or copied entry by entry
//! (the baseline), and the same plain-Rust lane loop then evaluates them.
//! The per-lane sums are added in a fixed tree at the end, so the result is
//! bitwise the same on every CPU and for any number of threads (Rust
//! contracts nothing into fused multiply-adds).

use sph_core::Neighbourhood;
#[cfg(target_arch = "x86_64")]
use sph_core::{Simd, simd_level};

use crate::anisotropy::Ellipsoid;

/// Neighbours per buffer.
const LANES: usize = 8;

/// A kernel as the sums read it, one row per slot of the grid: G² as
/// [xx, xy, xz, yy, yz, zz], then tr G², then V det G times poly6's
/// constant.
pub(crate) type SlotKernel = [f32; 8];

/// The row of kernel `e` whose V det G times poly6's constant is `weight`.
pub(crate) fn slot_kernel(e: &Ellipsoid, weight: f32) -> SlotKernel {
    let [xx, xy, xz, yy, yz, zz] = e.m;
    [xx, xy, xz, yy, yz, zz, e.trace(), weight]
}

/// The sums: c, ∇c (3), ∇²c, the second moment Σ d dᵀ of the offsets as
/// [xx, xy, xz, yy, yz, zz] (zeros unless asked for), and the neighbours
/// within h.
pub(crate) struct EllipsoidSums {
    pub(crate) value: [f32; 5],
    pub(crate) second: [f32; 6],
    pub(crate) count: u32,
}

/// Up to eight neighbours: slots, offsets centre − x_j per axis, and 1 for
/// a neighbour (0 in the lanes a last, partial buffer pads, which repeat
/// lane 0's slot at offset 0 and so add exact zeros).
struct Hits {
    slots: [u32; LANES],
    d: [[f32; LANES]; 3],
    w: [f32; LANES],
    n: usize,
}

/// Per-lane sums: c, ∇c (3), ∇²c, then the second moment's six.
type Lanes = [[f32; LANES]; 11];

/// How a full buffer's kernels are loaded.
#[derive(Clone, Copy)]
enum Load {
    #[cfg(target_arch = "x86_64")]
    Avx2,
    Scalar,
}

/// The sums of the kernels `kernels` (one per slot of `nb`'s grid) over
/// `nb`, whose grid has h² = `h2`; the second moment when `SECOND`.
///
/// # Panics
/// If `kernels` has fewer rows than the grid has slots.
#[inline]
pub(crate) fn ellipsoid_sums<const SECOND: bool>(
    nb: Neighbourhood<'_>,
    kernels: &[SlotKernel],
    slots: usize,
    h2: f32,
) -> EllipsoidSums {
    assert!(kernels.len() >= slots, "a kernel per slot");
    #[cfg(target_arch = "x86_64")]
    let load = if simd_level() >= Simd::Avx2 {
        Load::Avx2
    } else {
        Load::Scalar
    };
    #[cfg(not(target_arch = "x86_64"))]
    let load = Load::Scalar;
    let mut hits = Hits {
        slots: [0; LANES],
        d: [[0.0; LANES]; 3],
        w: [1.0; LANES],
        n: 0,
    };
    let mut acc: Lanes = [[0.0; LANES]; 11];
    let mut count = 0u32;
    nb.for_each_slot(|k, d, _| {
        let n = hits.n;
        hits.slots[n] = k as u32;
        hits.d[0][n] = d.x;
        hits.d[1][n] = d.y;
        hits.d[2][n] = d.z;
        hits.w[n] = 1.0;
        hits.n = n + 1;
        count += 1;
        if hits.n == LANES {
            flush::<SECOND>(&mut hits, kernels, h2, &mut acc, load);
        }
    });
    if hits.n > 0 {
        for l in hits.n..LANES {
            hits.slots[l] = hits.slots[0];
            for axis in &mut hits.d {
                axis[l] = 0.0;
            }
            hits.w[l] = 0.0;
        }
        flush::<SECOND>(&mut hits, kernels, h2, &mut acc, load);
    }
    let total =
        |l: &[f32; LANES]| ((l[0] + l[1]) + (l[2] + l[3])) + ((l[4] + l[5]) + (l[6] + l[7]));
    let r = acc.map(|l| total(&l));
    EllipsoidSums {
        value: [r[0], r[1], r[2], r[3], r[4]],
        second: [r[5], r[6], r[7], r[8], r[9], r[10]],
        count,
    }
}

/// Adds a full (or padded) buffer to the lanes and empties it.
#[inline]
fn flush<const SECOND: bool>(
    hits: &mut Hits,
    kernels: &[SlotKernel],
    h2: f32,
    acc: &mut Lanes,
    load: Load,
) {
    match load {
        // SAFETY: `Load::Avx2` is chosen only where the CPU has AVX2, and the
        // buffer holds slots of the grid, each with a row (asserted in
        // `ellipsoid_sums`).
        #[cfg(target_arch = "x86_64")]
        Load::Avx2 => unsafe { add_avx2::<SECOND>(hits, kernels, h2, acc) },
        Load::Scalar => {
            let mut g = [[0.0f32; LANES]; 8];
            for (l, &s) in hits.slots.iter().enumerate() {
                for (e, v) in kernels[s as usize].iter().enumerate() {
                    g[e][l] = *v;
                }
            }
            add::<SECOND>(&g, hits, h2, acc);
        }
    }
    hits.n = 0;
}

/// The buffer's eight kernel rows loaded whole and transposed in registers
/// (an 8 × 8 transpose: unpack, shuffle, then swap 128-bit halves), then
/// [`add`].
///
/// # Safety
/// The CPU must support AVX2, and every slot in `hits` must index `kernels`.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn add_avx2<const SECOND: bool>(
    hits: &Hits,
    kernels: &[SlotKernel],
    h2: f32,
    acc: &mut Lanes,
) {
    use std::arch::x86_64::*;
    // SAFETY: the caller guarantees the slots index `kernels`; a row is 8
    // contiguous floats.
    let r: [__m256; LANES] = std::array::from_fn(|l| unsafe {
        _mm256_loadu_ps(kernels.as_ptr().add(hits.slots[l] as usize).cast::<f32>())
    });
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
    let columns = [
        _mm256_permute2f128_ps::<0x20>(s0, s4),
        _mm256_permute2f128_ps::<0x20>(s1, s5),
        _mm256_permute2f128_ps::<0x20>(s2, s6),
        _mm256_permute2f128_ps::<0x20>(s3, s7),
        _mm256_permute2f128_ps::<0x31>(s0, s4),
        _mm256_permute2f128_ps::<0x31>(s1, s5),
        _mm256_permute2f128_ps::<0x31>(s2, s6),
        _mm256_permute2f128_ps::<0x31>(s3, s7),
    ];
    let mut g = [[0.0f32; LANES]; 8];
    for (e, c) in columns.into_iter().enumerate() {
        // SAFETY: `g[e]` is 8 floats.
        unsafe { _mm256_storeu_ps(g[e].as_mut_ptr(), c) };
    }
    add::<SECOND>(&g, hits, h2, acc);
}

/// The buffer's terms into the lanes: `g[e][l]` is entry e of lane l's
/// kernel row.
// Lane loops index several arrays by lane, which is what vectorises.
#[allow(clippy::needless_range_loop)]
#[inline(always)]
fn add<const SECOND: bool>(g: &[[f32; LANES]; 8], hits: &Hits, h2: f32, acc: &mut Lanes) {
    for k in 0..LANES {
        let [dx, dy, dz] = [hits.d[0][k], hits.d[1][k], hits.d[2][k]];
        // M d, with M = G² as [xx, xy, xz, yy, yz, zz].
        let mx = g[0][k] * dx + g[1][k] * dy + g[2][k] * dz;
        let my = g[1][k] * dx + g[3][k] * dy + g[4][k] * dz;
        let mz = g[2][k] * dx + g[4][k] * dy + g[5][k] * dz;
        // f = (h² − q)³, ∇f = −3t² · 2Md, ∇²f = 24t|Md|² − 6t² tr M, with
        // t = h² − q; every term is 0 outside the kernel (t = 0), which the
        // `max` makes so without a branch, and in the padding (w = 0).
        let t = (h2 - (dx * mx + dy * my + dz * mz)).max(0.0);
        let at = hits.w[k] * g[7][k] * t;
        let at2 = at * t;
        acc[0][k] += at2 * t;
        let grad = -6.0 * at2;
        acc[1][k] += grad * mx;
        acc[2][k] += grad * my;
        acc[3][k] += grad * mz;
        acc[4][k] += at * (24.0 * (mx * mx + my * my + mz * mz)) - 6.0 * at2 * g[6][k];
        if SECOND {
            let w = hits.w[k];
            let (wx, wy, wz) = (w * dx, w * dy, w * dz);
            acc[5][k] += wx * dx;
            acc[6][k] += wx * dy;
            acc[7][k] += wx * dz;
            acc[8][k] += wy * dy;
            acc[9][k] += wy * dz;
            acc[10][k] += wz * dz;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The AVX2 transpose loads the same rows as the entry-by-entry copy:
    /// both paths give bitwise the same sums.
    #[test]
    fn both_loads_give_the_same_sums() {
        let kernels: Vec<SlotKernel> = (0..40)
            .map(|i| std::array::from_fn(|e| (i * 8 + e) as f32 * 0.01 + 0.5))
            .collect();
        let mut hits = Hits {
            slots: [3, 17, 5, 39, 0, 22, 8, 11],
            d: [[0.001; LANES], [-0.002; LANES], [0.0005; LANES]],
            w: [1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 0.0, 0.0],
            n: 8,
        };
        let run = |load, hits: &mut Hits| {
            let mut acc: Lanes = [[0.0; LANES]; 11];
            hits.n = 8;
            flush::<true>(hits, &kernels, 0.01, &mut acc, load);
            acc.map(|l| l.map(f32::to_bits))
        };
        let scalar = run(Load::Scalar, &mut hits);
        assert!(scalar[0].iter().any(|&b| f32::from_bits(b) > 0.0));
        #[cfg(target_arch = "x86_64")]
        if std::is_x86_feature_detected!("avx2") {
            assert_eq!(run(Load::Avx2, &mut hits), scalar);
        }
    }
}
