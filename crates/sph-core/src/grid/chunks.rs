//! A neighbourhood's hits in chunks of 16 lanes, for sums written as plain
//! lane loops by the grid's users (the anisotropic surface field of
//! `surfel-extract`, say), and the hits alone in the same chunks for sums that
//! gather their own data (`Neighbourhood::hit_chunks`).
//!
//! Hit m of a neighbourhood (in slot order, row by row) goes to lane m mod 16
//! of its chunk. The scan's fills end at counts that depend on the vector
//! path, so a fill's last partial chunk is carried to the front of the buffer
//! and completed by the next fill: only the neighbourhood's last chunk is
//! partial, on every path, and a lane loop over the chunks followed by
//! [`reduce_lanes`] gives bitwise the same sums on every CPU and for any
//! number of threads (Rust contracts nothing into fused multiply-adds).
//!
//! The WCSPH force sums use `hit_chunks`: driven by [`Chunks`],
//! which also gathers each lane's offset, the 100k WCSPH step measured
//! 5–8 % slower (`docs/benchmark-notes.md`, "Anisotropic sums in slot
//! order").

use glam::Vec3;

use super::{Neighbourhood, SlotRange, scan};
use crate::simd::F32x8;

/// Lanes of a [`Chunk`].
pub const CHUNK_LANES: usize = LANES;

/// Up to [`CHUNK_LANES`] neighbours of a centre, one per lane.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Chunk {
    /// The neighbours' slots (see [`super::NeighbourGrid::order`]); lanes
    /// past `len` repeat lane 0's.
    pub slots: [u32; CHUNK_LANES],
    /// Lanes holding a neighbour, 1 to [`CHUNK_LANES`].
    pub len: usize,
    /// 1 for the lanes holding a neighbour, 0 past `len`: multiplying a
    /// term by it adds exact zeros for the repeated lanes, whose values are
    /// lane 0's and so finite.
    pub weight: [f32; CHUNK_LANES],
    /// centre − x_j, per axis.
    pub d: [[f32; CHUNK_LANES]; 3],
    /// |centre − x_j|², the value the scan tested against h².
    pub r2: [f32; CHUNK_LANES],
}

/// Lanes of every chunk and of every 16-lane sum.
const LANES: usize = 16;

/// Sums 16 lanes by the tree the AVX-512 paths use: lane i + lane i+8,
/// then i + i+4, i + i+2, and the last two.
#[inline]
fn reduce(l: &[f32; LANES]) -> f32 {
    let a: [f32; 8] = std::array::from_fn(|i| l[i] + l[i + 8]);
    let b: [f32; 4] = std::array::from_fn(|i| a[i] + a[i + 4]);
    let c: [f32; 2] = std::array::from_fn(|i| b[i] + b[i + 2]);
    c[0] + c[1]
}

/// Sums 16 lanes by the grid's fixed tree (lane i + lane i+8, then i + i+4,
/// i + i+2, and the last two), as every 16-lane sum over a neighbourhood
/// is reduced.
#[inline]
pub fn reduce_lanes(lanes: &[f32; CHUNK_LANES]) -> f32 {
    reduce(lanes)
}

/// [`reduce_lanes`] of 16 lanes held as two halves of [`F32x8`] (lanes 0–7
/// and 8–15), as the lane code over the chunks keeps them.
#[inline(always)]
pub fn reduce_halves<S: F32x8>(lo: S, hi: S) -> f32 {
    let mut lanes = [0.0; CHUNK_LANES];
    lo.store_half(&mut lanes, 0);
    hi.store_half(&mut lanes, 1);
    reduce(&lanes)
}

impl Neighbourhood<'_> {
    /// The neighbourhood's hits (slots, see
    /// [`super::NeighbourGrid::order`]) in chunks of [`CHUNK_LANES`], hit m
    /// at index m mod 16 of its chunk, only the last chunk partial: the
    /// lighter loop under [`Neighbourhood::chunks`], for sums that gather
    /// their own per-slot data (the WCSPH force sums, in
    /// `solver/force_sums.rs`). Drive it with `while let Some(fill) =
    /// hits.next_fill()` and `for chunk in fill.chunks(CHUNK_LANES)`, the
    /// body in place: a closure may be left out of line, compiled without
    /// the caller's target features.
    #[inline(always)]
    pub(crate) fn hit_chunks(&self) -> HitChunks<'_> {
        let [xs, ys, zs] = &self.grid.layout.coords;
        HitChunks {
            scan: scan::Scan::new(self.centre, self.grid.h2, [xs, ys, zs], &self.rows),
            hits: scan::Hits::new(),
            n: 0,
            whole: 0,
            done: false,
        }
    }

    /// The grid's coordinates by slot (x, y, z; padded past the last slot),
    /// the values its scan tests.
    #[inline(always)]
    pub(crate) fn slot_coords(&self) -> [&[f32]; 3] {
        let [xs, ys, zs] = &self.grid.layout.coords;
        [xs, ys, zs]
    }

    /// The grid's h and h².
    #[inline(always)]
    pub(crate) fn radius(&self) -> (f32, f32) {
        (self.grid.h, self.grid.h2)
    }

    /// The 9 slot ranges (rows of cells) the query scans, in scan order.
    #[inline(always)]
    pub(crate) fn rows(&self) -> &[SlotRange; 9] {
        &self.rows
    }

    /// Slots in the grid.
    #[inline(always)]
    pub(crate) fn slots(&self) -> usize {
        self.grid.len()
    }

    /// The neighbours (within h of the centre, the centre particle itself
    /// included for a particle's neighbourhood) in chunks of [`CHUNK_LANES`],
    /// hit m in lane m mod 16; only the last chunk may be partial.
    ///
    /// The iterator is inlined into the loop that drives it, so a caller
    /// compiled for wider vectors (`#[target_feature]`) gets them here too;
    /// write the loop's body in place rather than in a closure, which the
    /// compiler may leave out of line, compiled without those features.
    #[inline(always)]
    pub fn chunks(&self) -> Chunks<'_> {
        let [xs, ys, zs] = &self.grid.layout.coords;
        Chunks {
            scan: scan::Scan::new(self.centre, self.grid.h2, [xs, ys, zs], &self.rows),
            coords: [xs, ys, zs],
            centre: self.centre,
            hits: scan::Hits::new(),
            n: 0,
            whole: 0,
            next: 0,
            done: false,
        }
    }
}

/// The chunks of [`Neighbourhood::hit_chunks`]. The scan's fills end at
/// path-dependent counts, so a fill's last partial chunk is carried to the
/// front of the buffer and completed by the next fill.
pub(crate) struct HitChunks<'a> {
    scan: scan::Scan<'a>,
    hits: scan::Hits<{ scan::HIT_CAPACITY }>,
    /// Hits in the buffer, and the end of its whole chunks.
    n: usize,
    whole: usize,
    done: bool,
}

impl HitChunks<'_> {
    /// The hits of the scan's next fill that make whole chunks (all of
    /// them at the last fill), the partial chunk before them carried in;
    /// `None` after the last. Split the slice with `chunks(CHUNK_LANES)`.
    #[inline(always)]
    pub(crate) fn next_fill(&mut self) -> Option<&[u32]> {
        if self.done {
            return None;
        }
        let carried = self.n - self.whole;
        self.hits.copy_within(self.whole..self.n, 0);
        self.n = self.scan.fill(&mut self.hits, carried);
        self.done = self.scan.done();
        self.whole = if self.done {
            self.n
        } else {
            self.n - self.n % CHUNK_LANES
        };
        Some(&self.hits[..self.whole])
    }
}

/// The iterator of [`Neighbourhood::chunks`].
pub struct Chunks<'a> {
    scan: scan::Scan<'a>,
    coords: [&'a [f32]; 3],
    centre: Vec3,
    /// The scan's hits; `hits[next..whole]` are still to go out in chunks,
    /// `hits[whole..n]` are a partial chunk carried into the next fill.
    hits: scan::Hits<{ scan::HIT_CAPACITY }>,
    n: usize,
    whole: usize,
    next: usize,
    done: bool,
}

impl Chunks<'_> {
    /// The next chunk's slots and how many lanes hold a hit. The scan's
    /// fills end at path-dependent counts, so a fill's last partial chunk
    /// is carried to the front of the buffer and completed by the next fill.
    #[inline(always)]
    fn next_hits(&mut self) -> Option<([u32; LANES], usize)> {
        loop {
            if self.next < self.whole {
                let len = (self.whole - self.next).min(LANES);
                let hits = &self.hits[self.next..self.next + len];
                // Lanes past the hits repeat the chunk's first.
                let mut slots = [hits[0]; LANES];
                slots[..len].copy_from_slice(hits);
                self.next += len;
                return Some((slots, len));
            }
            if self.done {
                return None;
            }
            self.hits.copy_within(self.whole..self.n, 0);
            let carried = self.n - self.whole;
            self.n = self.scan.fill(&mut self.hits, carried);
            self.done = self.scan.done();
            self.whole = if self.done {
                self.n
            } else {
                self.n - self.n % LANES
            };
            self.next = 0;
        }
    }
}

impl Iterator for Chunks<'_> {
    type Item = Chunk;

    // Lane loops index several arrays by lane, which is what vectorises.
    #[allow(clippy::needless_range_loop)]
    #[inline(always)]
    fn next(&mut self) -> Option<Chunk> {
        let (slots, len) = self.next_hits()?;
        let [xs, ys, zs] = self.coords;
        let c = self.centre;
        let mut weight = [0.0f32; CHUNK_LANES];
        weight[..len].fill(1.0);
        let mut chunk = Chunk {
            slots,
            len,
            weight,
            d: [[0.0; CHUNK_LANES]; 3],
            r2: [0.0; CHUNK_LANES],
        };
        let mut x = [[0.0f32; CHUNK_LANES]; 3];
        for (k, &s) in slots.iter().enumerate() {
            let s = s as usize;
            // SAFETY: hits are slots of the grid, which has a coordinate per
            // slot.
            unsafe {
                x[0][k] = *xs.get_unchecked(s);
                x[1][k] = *ys.get_unchecked(s);
                x[2][k] = *zs.get_unchecked(s);
            }
        }
        for k in 0..CHUNK_LANES {
            // The scan's arithmetic, so r² is the value it tested.
            let d = [c.x - x[0][k], c.y - x[1][k], c.z - x[2][k]];
            chunk.r2[k] = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
            for a in 0..3 {
                chunk.d[a][k] = d[a];
            }
        }
        Some(chunk)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::NeighbourGrid;

    /// The chunks hold exactly `for_each_slot`'s neighbours, in its order,
    /// with its offsets and squared distances; only the last is partial.
    #[test]
    fn chunks_hold_the_neighbours_in_slot_order() {
        let mut x = Vec::new();
        for k in 0..9 {
            for j in 0..9 {
                for i in 0..9 {
                    let jitter = ((i * 7 + j * 13 + k * 29) % 11) as f32 * 1e-3;
                    x.push(Vec3::new(i as f32, j as f32, k as f32) * 0.02 + jitter);
                }
            }
        }
        let grid = NeighbourGrid::build(&x, 0.05).unwrap();
        for centre in [x[0], x[364], Vec3::new(0.08, 0.1, 0.07), Vec3::splat(5.0)] {
            let nb = grid.neighbourhood_of_point(centre);
            let mut want = Vec::new();
            nb.for_each_slot(|k, d, r2| want.push((k as u32, d, r2)));
            let mut got = Vec::new();
            let mut partial = 0;
            for ch in nb.chunks() {
                assert!(partial == 0, "a partial chunk before the last");
                if ch.len < CHUNK_LANES {
                    partial += 1;
                }
                for k in 0..CHUNK_LANES {
                    let held = k < ch.len;
                    assert_eq!(ch.weight[k], if held { 1.0 } else { 0.0 });
                    if held {
                        let d = Vec3::new(ch.d[0][k], ch.d[1][k], ch.d[2][k]);
                        got.push((ch.slots[k], d, ch.r2[k]));
                    } else {
                        assert_eq!(ch.slots[k], ch.slots[0]);
                    }
                }
            }
            assert_eq!(got, want, "centre {centre}");
        }
    }

    #[test]
    fn lanes_reduce_by_the_fixed_tree() {
        let l: [f32; CHUNK_LANES] = std::array::from_fn(|i| (i as f32 + 1.0) * 0.1);
        let by_hand = {
            let a: Vec<f32> = (0..8).map(|i| l[i] + l[i + 8]).collect();
            let b: Vec<f32> = (0..4).map(|i| a[i] + a[i + 4]).collect();
            (b[0] + b[2]) + (b[1] + b[3])
        };
        assert_eq!(reduce_lanes(&l).to_bits(), by_hand.to_bits());
    }
}
