//! The distance test over a neighbourhood's rows, vectorised.
//!
//! A [`Scan`] walks the 9 slot ranges ("rows") of a neighbourhood and writes the
//! slots within h of the centre into a hit buffer, a chunk of candidates at a
//! time: eight [`F32x8`] lanes (the kind [`with_lanes`] picks: AVX2, SSE2 or
//! plain arrays), or 16 with AVX-512F. The chunks write their hits branch-free
//! (packed in a register and stored whole: [`F32x8::pack_le`], AVX-512's
//! compress), and the caller then visits the buffer in one loop: its closure has
//! a single call site, so the compiler inlines it and keeps the caller's sums in
//! registers.
//!
//! The AVX-512 path is the one piece of SIMD outside [`crate::simd`]: its
//! 16-lane compress made the neighbour search 8 % faster than the AVX2 path on
//! the one AVX-512 machine measured (BENCHMARKS.md, "CPU paths side by side"),
//! and the room's lanes are eight wide.
//!
//! Every path computes `d = c − x` and `d.x² + d.y² + d.z²` with the same
//! operations in the same order (no fused multiply-add), so all of them accept
//! exactly the same slots, which are the brute-force set; the buffer holds them in
//! increasing slot order, row by row.

use glam::Vec3;

use super::SlotRange;
use crate::simd::{F32x8, LaneFn, with_lanes};
#[cfg(target_arch = "x86_64")]
use crate::simd::{Simd, simd_level};

/// Entries past the last slot that the coordinate arrays must carry (any finite
/// or NaN value): the eight-lane path loads whole chunks of 8.
pub(super) const PADDING: usize = 7;

/// Hit buffer size of the scans that keep a buffer for many neighbourhoods
/// or carry chunks across fills; a fill stops while at least one 16-lane
/// chunk still fits, whatever the buffer's size.
pub(crate) const HIT_CAPACITY: usize = 256;

/// Hit buffer size of a one-off scan ([`super::Neighbourhood::for_each_slot`]):
/// a neighbourhood of h holds a few dozen hits, and each query zeroes its
/// buffer, which at 256 entries took 3 % of an anisotropic extraction.
pub(super) const QUERY_CAPACITY: usize = 64;

/// A scan's hit buffer of `N` slots, aligned to 1 KiB so that the fills'
/// 16-lane stores never straddle a 4 KiB page (a buffer of at most 256
/// slots lies within one aligned KiB). A store across a page boundary is
/// slow, and where the stack put an unaligned buffer decided whether a
/// build's neighbour lists took half as long again (`docs/benchmark-notes.md`,
/// "Hit buffers across a page").
#[derive(Clone)]
#[repr(C, align(1024))]
pub(crate) struct Hits<const N: usize>(pub [u32; N]);

impl<const N: usize> Hits<N> {
    /// A zeroed buffer.
    pub(crate) const fn new() -> Self {
        const { assert!(N <= 256, "a hit buffer beyond 1 KiB could straddle a page") };
        Self([0; N])
    }
}

impl<const N: usize> std::ops::Deref for Hits<N> {
    type Target = [u32; N];
    fn deref(&self) -> &[u32; N] {
        &self.0
    }
}

impl<const N: usize> std::ops::DerefMut for Hits<N> {
    fn deref_mut(&mut self) -> &mut [u32; N] {
        &mut self.0
    }
}

/// The widest chunk any path writes.
const MAX_LANES: usize = 16;

/// Candidates over the rows of one neighbourhood, resumable: each
/// [`Scan::fill`] continues where the previous one stopped.
pub(super) struct Scan<'a> {
    centre: Vec3,
    h2: f32,
    coords: [&'a [f32]; 3],
    rows: &'a [SlotRange; 9],
    row: usize,
    slot: usize,
}

impl<'a> Scan<'a> {
    /// A scan of `rows` for slots within `sqrt(h2)` of `centre`. Each coordinate
    /// array must extend [`PADDING`] entries past the last row's end.
    #[inline]
    pub(super) fn new(
        centre: Vec3,
        h2: f32,
        coords: [&'a [f32]; 3],
        rows: &'a [SlotRange; 9],
    ) -> Self {
        let len = coords.iter().map(|c| c.len()).min().unwrap_or(0);
        assert!(
            rows.iter().all(|r| r.end as usize + PADDING <= len),
            "coordinate arrays must be padded past every row"
        );
        Self {
            centre,
            h2,
            coords,
            rows,
            row: 0,
            slot: rows[0].start as usize,
        }
    }

    /// Whether every row has been scanned.
    #[inline]
    pub(super) fn done(&self) -> bool {
        self.row >= self.rows.len()
    }

    /// Writes the next hits (slots) into `hits` after its first `start`
    /// entries (at most 16, left as they are) and returns the new count; fewer
    /// than the capacity does not mean the scan is done, see [`Scan::done`].
    /// Where a fill stops depends on the path's chunk width.
    #[inline]
    pub(super) fn fill<const N: usize>(&mut self, hits: &mut [u32; N], start: usize) -> usize {
        const {
            assert!(
                N >= 2 * MAX_LANES,
                "room for a chunk carried over and one more"
            )
        };
        assert!(start <= MAX_LANES, "at most one chunk carried over");
        #[cfg(target_arch = "x86_64")]
        if simd_level() == Simd::Avx512 {
            // SAFETY: `simd_level` never exceeds what the CPU supports
            // (AVX-512F and POPCNT).
            return unsafe { self.fill_avx512(hits, start) };
        }
        with_lanes(Fill {
            scan: self,
            hits,
            start,
        })
    }

    /// The row loop of the AVX-512 path and of the tests' scalar reference
    /// (the lanes' [`Fill`] writes it out): `chunk(k, end, hits, n)` tests the
    /// slots from `k` (at most `LANES` of them, none at or past `end`), appends
    /// the hits at `hits[n..]` and returns the new count; the first chunk
    /// appends at `hits[start..]`.
    #[cfg_attr(not(any(test, target_arch = "x86_64")), allow(dead_code))]
    #[inline(always)]
    fn drive<const LANES: usize, const N: usize>(
        &mut self,
        hits: &mut [u32; N],
        start: usize,
        mut chunk: impl FnMut(usize, usize, &mut [u32; N], usize) -> usize,
    ) -> usize {
        let mut n = start;
        while self.row < self.rows.len() {
            let end = self.rows[self.row].end as usize;
            while self.slot < end {
                if n > N - MAX_LANES {
                    return n;
                }
                n = chunk(self.slot, end, hits, n);
                self.slot += LANES;
            }
            self.row += 1;
            if let Some(next) = self.rows.get(self.row) {
                self.slot = next.start as usize;
            }
        }
        n
    }

    /// One candidate at a time: the reference the vector paths are tested against.
    #[cfg(test)]
    fn fill_scalar<const N: usize>(&mut self, hits: &mut [u32; N], start: usize) -> usize {
        let (c, h2, [xs, ys, zs]) = (self.centre, self.h2, self.coords);
        self.drive::<1, N>(hits, start, |k, _, hits, n| {
            let d = Vec3::new(c.x - xs[k], c.y - ys[k], c.z - zs[k]);
            hits[n] = k as u32;
            n + usize::from(d.x * d.x + d.y * d.y + d.z * d.z <= h2)
        })
    }

    /// Sixteen candidates at a time, masked loads at a row's end, hits packed
    /// by a compress and written with one store.
    ///
    /// # Safety
    /// The CPU must support AVX-512F and POPCNT.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f,popcnt")]
    unsafe fn fill_avx512<const N: usize>(&mut self, hits: &mut [u32; N], start: usize) -> usize {
        use std::arch::x86_64::*;
        let (c, h2, [xs, ys, zs]) = (self.centre, self.h2, self.coords);
        let (cx, cy, cz) = (
            _mm512_set1_ps(c.x),
            _mm512_set1_ps(c.y),
            _mm512_set1_ps(c.z),
        );
        let lim = _mm512_set1_ps(h2);
        let lane = _mm512_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
        self.drive::<16, N>(hits, start, |k, end, hits, n| {
            let valid: __mmask16 = if end - k >= 16 {
                u16::MAX
            } else {
                (1u16 << (end - k)) - 1
            };
            // SAFETY: the masked loads touch only lanes k..end, inside the arrays;
            // the store writes 16 entries at hits[n..], and the driver calls with
            // n <= N - MAX_LANES (N >= 2 MAX_LANES, asserted in `fill`).
            debug_assert!(n + 16 <= N);
            unsafe {
                let x = _mm512_maskz_loadu_ps(valid, xs.as_ptr().add(k));
                let y = _mm512_maskz_loadu_ps(valid, ys.as_ptr().add(k));
                let z = _mm512_maskz_loadu_ps(valid, zs.as_ptr().add(k));
                let (_, r2) = offsets_avx512([cx, cy, cz], [x, y, z]);
                let mask = _mm512_mask_cmp_ps_mask::<_CMP_LE_OQ>(valid, r2, lim);
                let slots = _mm512_add_epi32(_mm512_set1_epi32(k as i32), lane);
                // Compress in a register and store all 16 lanes: much faster than
                // a compress-store to memory; lanes past the hits are overwritten
                // by the next chunk or ignored.
                let packed = _mm512_maskz_compress_epi32(mask, slots);
                _mm512_storeu_si512(hits.as_mut_ptr().add(n).cast(), packed);
                n + mask.count_ones() as usize
            }
        })
    }
}

/// One [`Scan::fill`] over [`F32x8`] lanes: eight candidates at a time,
/// each chunk's hits packed to the front of the buffer
/// ([`F32x8::pack_le`]).
struct Fill<'s, 'a, const N: usize> {
    scan: &'s mut Scan<'a>,
    hits: &'s mut [u32; N],
    start: usize,
}

impl<const N: usize> LaneFn for Fill<'_, '_, N> {
    type Out = usize;

    /// [`Scan::drive`]'s loop written out: the lanes must not live in a
    /// closure (see [`LaneFn`]).
    #[inline(always)]
    fn call<S: F32x8>(self) -> usize {
        let Fill { scan, hits, start } = self;
        // The scan's state in locals, written back on return: through the
        // `&mut Scan` the compiler would reload it after every store of hits.
        let (rows, [xs, ys, zs]) = (scan.rows, scan.coords);
        let (mut row, mut slot) = (scan.row, scan.slot);
        let c = scan.centre;
        let cs = [S::splat(c.x), S::splat(c.y), S::splat(c.z)];
        let lim = S::splat(scan.h2);
        let mut n = start;
        'rows: while row < rows.len() {
            let end = rows[row].end as usize;
            while slot < end {
                if n > N - MAX_LANES {
                    break 'rows;
                }
                // SAFETY: slot < end and the arrays extend PADDING = 7
                // entries past every row's end (asserted in `new`), so
                // xs/ys/zs[slot..slot + 8] are in bounds; lanes at or past
                // `end` are left out of the hits.
                let (x, y, z) = unsafe {
                    (
                        S::load_unchecked(xs.as_ptr().add(slot)),
                        S::load_unchecked(ys.as_ptr().add(slot)),
                        S::load_unchecked(zs.as_ptr().add(slot)),
                    )
                };
                let (dx, dy, dz) = (cs[0] - x, cs[1] - y, cs[2] - z);
                let r2 = dx * dx + dy * dy + dz * dz;
                n += r2.pack_le(lim, end - slot, slot as u32, &mut hits[n..]);
                slot += 8;
            }
            row += 1;
            if let Some(next) = rows.get(row) {
                slot = next.start as usize;
            }
        }
        (scan.row, scan.slot) = (row, slot);
        n
    }
}

/// d = c − x and d.x² + d.y² + d.z² for 16 lanes: the expression, in the
/// order, that every path tests against h² (no fused multiply-add).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
#[inline]
fn offsets_avx512(
    c: [std::arch::x86_64::__m512; 3],
    x: [std::arch::x86_64::__m512; 3],
) -> ([std::arch::x86_64::__m512; 3], std::arch::x86_64::__m512) {
    use std::arch::x86_64::*;
    let d = [
        _mm512_sub_ps(c[0], x[0]),
        _mm512_sub_ps(c[1], x[1]),
        _mm512_sub_ps(c[2], x[2]),
    ];
    let r2 = _mm512_add_ps(
        _mm512_add_ps(_mm512_mul_ps(d[0], d[0]), _mm512_mul_ps(d[1], d[1])),
        _mm512_mul_ps(d[2], d[2]),
    );
    (d, r2)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Hit buffers on the stack and in a struct lie within one 4 KiB page,
    /// wherever the stack happens to be.
    #[test]
    fn hit_buffers_never_straddle_a_page() {
        fn within_a_page<const N: usize>(h: &Hits<N>) -> bool {
            let start = h.as_ptr() as usize;
            start / 4096 == (start + 4 * N - 1) / 4096
        }
        // Frames of many sizes above the buffer.
        fn nested(depth: usize, pad: &[u8]) -> bool {
            let mut local = [0u8; 24];
            local[depth % 24] = pad.len() as u8;
            let hits = Hits::<HIT_CAPACITY>::new();
            let query = Hits::<QUERY_CAPACITY>::new();
            within_a_page(&hits)
                && within_a_page(&query)
                && (depth == 0 || nested(depth - 1, &local[..depth % 24]))
        }
        assert!(nested(40, &[]));
        let boxed: Vec<Hits<HIT_CAPACITY>> = vec![Hits::new(); 9];
        assert!(boxed.iter().all(within_a_page));
    }

    /// Runs a scan to the end with `fill` into a buffer of `N`, collecting
    /// every hit.
    fn all_hits<const N: usize>(
        mut scan: Scan<'_>,
        fill: impl Fn(&mut Scan<'_>, &mut [u32; N]) -> usize,
    ) -> Vec<u32> {
        let mut hits = [0u32; N];
        let mut out = Vec::new();
        while !scan.done() {
            let n = fill(&mut scan, &mut hits);
            out.extend_from_slice(&hits[..n]);
        }
        out
    }

    /// Every vector path finds exactly the scalar path's hits, in the same order,
    /// on rows of every length mod 16 (masked tails), hits on lane boundaries,
    /// points exactly at distance h, and more hits than one buffer holds.
    #[test]
    fn vector_paths_equal_the_scalar_path() {
        let mut state = 0x9E37_79B9u32;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            (state as f32 / u32::MAX as f32) * 2.0 - 1.0
        };
        let n = 1000;
        let mut coords: [Vec<f32>; 3] = Default::default();
        for c in coords.iter_mut() {
            c.extend((0..n).map(|_| next()));
        }
        // Exactly at distance 1 along x, and coincident with the centre.
        coords[0][17] = 1.0;
        coords[1][17] = 0.0;
        coords[2][17] = 0.0;
        for c in coords.iter_mut() {
            c[18] = 0.0;
            c.extend([f32::NAN; PADDING]);
        }
        let mut starts: Vec<u32> = (0..9).map(|r| r * 97).collect();
        starts.sort_unstable();
        for len in [0u32, 1, 3, 4, 5, 15, 16, 17, 33, 600] {
            let rows: [SlotRange; 9] = std::array::from_fn(|r| {
                let start = starts[r];
                SlotRange {
                    start,
                    end: (start + len + r as u32).min(n as u32),
                }
            });
            let view = [&coords[0][..], &coords[1][..], &coords[2][..]];
            let scan = || Scan::new(Vec3::ZERO, 1.0, view, &rows);
            let scalar = all_hits::<HIT_CAPACITY>(scan(), |s, h| s.fill_scalar(h, 0));
            let brute: Vec<u32> = rows
                .iter()
                .flat_map(|r| r.start..r.end)
                .filter(|&k| {
                    let k = k as usize;
                    let (x, y, z) = (view[0][k], view[1][k], view[2][k]);
                    x * x + y * y + z * z <= 1.0
                })
                .collect();
            assert_eq!(scalar, brute, "rows of {len}");
            assert_eq!(
                all_hits::<HIT_CAPACITY>(scan(), |s, h| s.fill(h, 0)),
                scalar,
                "rows of {len}"
            );
            // A one-off query's smaller buffer: more fills, the same hits.
            assert_eq!(
                all_hits::<QUERY_CAPACITY>(scan(), |s, h| s.fill(h, 0)),
                scalar,
                "a buffer of {QUERY_CAPACITY}, rows of {len}"
            );
            assert_eq!(
                all_hits::<QUERY_CAPACITY>(scan(), |s, h| s.fill_scalar(h, 0)),
                scalar,
                "scalar, a buffer of {QUERY_CAPACITY}, rows of {len}"
            );
            for lanes in crate::simd::Lanes::every() {
                let fill = |s: &mut Scan<'_>, h: &mut [u32; HIT_CAPACITY]| {
                    lanes.run(Fill {
                        scan: s,
                        hits: h,
                        start: 0,
                    })
                };
                assert_eq!(
                    all_hits(scan(), fill),
                    scalar,
                    "{}, rows of {len}",
                    lanes.name()
                );
                let fill = |s: &mut Scan<'_>, h: &mut [u32; QUERY_CAPACITY]| {
                    lanes.run(Fill {
                        scan: s,
                        hits: h,
                        start: 0,
                    })
                };
                let small = all_hits(scan(), fill);
                assert_eq!(
                    small,
                    scalar,
                    "{}, a small buffer, rows of {len}",
                    lanes.name()
                );
            }
            #[cfg(target_arch = "x86_64")]
            {
                if Simd::detect() >= Simd::Avx512 {
                    // SAFETY: AVX-512F and POPCNT were detected.
                    let avx =
                        all_hits::<HIT_CAPACITY>(scan(), |s, h| unsafe { s.fill_avx512(h, 0) });
                    assert_eq!(avx, scalar, "AVX-512, rows of {len}");
                    // SAFETY: as above.
                    let avx =
                        all_hits::<QUERY_CAPACITY>(scan(), |s, h| unsafe { s.fill_avx512(h, 0) });
                    assert_eq!(avx, scalar, "AVX-512, a small buffer, rows of {len}");
                }
            }
        }
    }
}
