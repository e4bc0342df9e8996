//! The anisotropic field's sums at a point: c, ∇c, ∇²c of the ellipsoidal
//! kernels det G · W_poly6(|G r|) over the kernels within h, eight at a time.
//!
//! The grid's scan hands over the neighbours one by one; they are buffered
//! eight at a time (hit m in lane m mod 8) with their offsets, and each full
//! buffer is added to per-lane sums over [`F32x8`] lanes (sph-core's SIMD room), the eight
//! kernels gathered as whole rows of 8 floats and transposed
//! ([`F32x8::gather_rows8`]). The per-lane sums are added in a fixed tree
//! at the end, so the result is bitwise the same on every CPU and for any
//! number of threads (Rust contracts nothing into fused multiply-adds).

use sph_core::Neighbourhood;
use sph_core::simd::{F32x8, LaneFn, Lanes};

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
#[derive(Clone, Copy)]
struct Hits {
    slots: [u32; LANES],
    d: [[f32; LANES]; 3],
    w: [f32; LANES],
    n: usize,
}

/// Per-lane sums: c, ∇c (3), ∇²c, then the second moment's six.
type Acc = [[f32; LANES]; 11];

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
    // Each full buffer is summed through the lanes' dispatch: the scan's
    // callback is a closure of its own, which a `#[target_feature]`
    // function around the whole loop would not compile for its lanes.
    let lanes = Lanes::best();
    let mut hits = Hits {
        slots: [0; LANES],
        d: [[0.0; LANES]; 3],
        w: [1.0; LANES],
        n: 0,
    };
    let mut acc: Acc = [[0.0; LANES]; 11];
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
            lanes.run(Flush::<SECOND> {
                hits: &hits,
                kernels,
                h2,
                acc: &mut acc,
            });
            hits.n = 0;
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
        lanes.run(Flush::<SECOND> {
            hits: &hits,
            kernels,
            h2,
            acc: &mut acc,
        });
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

/// One buffer added to the per-lane sums, for [`Lanes::run`].
struct Flush<'a, const SECOND: bool> {
    hits: &'a Hits,
    kernels: &'a [SlotKernel],
    h2: f32,
    acc: &'a mut Acc,
}

impl<const SECOND: bool> LaneFn for Flush<'_, SECOND> {
    type Out = ();
    #[inline(always)]
    fn call<S: F32x8>(self) {
        // Loops, not `array::map`: a closure would not be compiled for the
        // lanes' instructions (see `LaneFn`).
        let mut acc = [S::splat(0.0); 11];
        for (lanes, sums) in acc.iter_mut().zip(self.acc.iter()) {
            *lanes = S::from_array(*sums);
        }
        add::<S, SECOND>(self.hits, self.kernels, self.h2, &mut acc);
        for (sums, lanes) in self.acc.iter_mut().zip(acc) {
            *sums = lanes.to_array();
        }
    }
}

/// A full (or padded) buffer's terms into the lanes `acc`: c, ∇c (3), ∇²c,
/// then the second moment's six.
///
/// # Panics
/// If a slot in `hits` has no row in `kernels`.
#[inline(always)]
fn add<S: F32x8, const SECOND: bool>(
    hits: &Hits,
    kernels: &[SlotKernel],
    h2: f32,
    acc: &mut [S; 11],
) {
    let g = S::gather_rows8(kernels, &hits.slots);
    let (dx, dy, dz) = (
        S::from_array(hits.d[0]),
        S::from_array(hits.d[1]),
        S::from_array(hits.d[2]),
    );
    let w = S::from_array(hits.w);
    // M d, with M = G² as [xx, xy, xz, yy, yz, zz].
    let mx = g[0] * dx + g[1] * dy + g[2] * dz;
    let my = g[1] * dx + g[3] * dy + g[4] * dz;
    let mz = g[2] * dx + g[4] * dy + g[5] * dz;
    // f = (h² − q)³, ∇f = −3t² · 2Md, ∇²f = 24t|Md|² − 6t² tr M, with
    // t = h² − q; every term is 0 outside the kernel (t = 0), which the
    // `max` makes so without a branch, and in the padding (w = 0).
    let t = (S::splat(h2) - (dx * mx + dy * my + dz * mz)).max(S::splat(0.0));
    let at = w * g[7] * t;
    let at2 = at * t;
    acc[0] = acc[0] + at2 * t;
    let grad = S::splat(-6.0) * at2;
    acc[1] = acc[1] + grad * mx;
    acc[2] = acc[2] + grad * my;
    acc[3] = acc[3] + grad * mz;
    acc[4] = acc[4]
        + (at * (S::splat(24.0) * (mx * mx + my * my + mz * mz)) - S::splat(6.0) * at2 * g[6]);
    if SECOND {
        let (wx, wy, wz) = (w * dx, w * dy, w * dz);
        acc[5] = acc[5] + wx * dx;
        acc[6] = acc[6] + wx * dy;
        acc[7] = acc[7] + wx * dz;
        acc[8] = acc[8] + wy * dy;
        acc[9] = acc[9] + wy * dz;
        acc[10] = acc[10] + wz * dz;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One buffer's terms, as bits per lane.
    #[derive(Clone, Copy)]
    struct Buffer<'a> {
        hits: Hits,
        kernels: &'a [SlotKernel],
        h2: f32,
    }

    impl LaneFn for Buffer<'_> {
        type Out = [[f32; LANES]; 11];
        #[inline(always)]
        fn call<S: F32x8>(self) -> Self::Out {
            let mut acc = [S::splat(0.0); 11];
            add::<S, true>(&self.hits, self.kernels, self.h2, &mut acc);
            acc.map(S::to_array)
        }
    }

    /// Every kind of lanes gives bitwise the same terms, and the plain
    /// arrays' are the formula's.
    #[test]
    fn every_kind_gives_the_same_sums() {
        let kernels: Vec<SlotKernel> = (0..40)
            .map(|i| std::array::from_fn(|e| (i * 8 + e) as f32 * 0.01 + 0.5))
            .collect();
        let buffer = Buffer {
            hits: Hits {
                slots: [3, 17, 5, 39, 0, 22, 8, 11],
                d: [[0.001; LANES], [-0.002; LANES], [0.0005; LANES]],
                w: [1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 0.0, 0.0],
                n: 8,
            },
            kernels: &kernels,
            h2: 0.01,
        };
        let kinds = Lanes::every();
        let plain = kinds[0].run(buffer);
        // Lane 1 by the formula, in f64: slot 17's kernel at d.
        let g = kernels[17].map(f64::from);
        let d = [0.001f32, -0.002, 0.0005].map(f64::from);
        let md = [
            g[0] * d[0] + g[1] * d[1] + g[2] * d[2],
            g[1] * d[0] + g[3] * d[1] + g[4] * d[2],
            g[2] * d[0] + g[4] * d[1] + g[5] * d[2],
        ];
        let t = 0.01 - (d[0] * md[0] + d[1] * md[1] + d[2] * md[2]);
        let c = g[7] * t * t * t;
        assert!(
            (f64::from(plain[0][1]) - c).abs() < 1e-5 * c,
            "{} {c}",
            plain[0][1]
        );
        let dx = -6.0 * g[7] * t * t * md[0];
        assert!((f64::from(plain[1][1]) - dx).abs() < 1e-5 * dx.abs());
        assert_eq!(plain[5][1], 0.001f32 * 0.001, "the second moment's xx");
        assert_eq!(plain[0][6], 0.0, "a padded lane adds nothing");
        for kind in &kinds[1..] {
            let bits = |a: [[f32; LANES]; 11]| a.map(|l| l.map(f32::to_bits));
            assert_eq!(bits(kind.run(buffer)), bits(plain), "{}", kind.name());
        }
    }
}
