//! Fixed neighbour lists: each particle's neighbours found once, then reused
//! while the particles move a little (position-based solvers iterate on
//! them within a step, Macklin & Müller 2013).

use std::ops::Range;

use rayon::prelude::*;

use super::{NeighbourGrid, scan};
use crate::error::{Error, Result};
use crate::region::{self, Blocks};

/// Particles per block when building lists (each block fills its own
/// buffers, copied into place after) and of `par_map_rows`: a fixed size, so
/// the result does not depend on the number of threads. 128 makes 79
/// blocks of 10k particles, enough for 16 threads to share evenly (512 made
/// 20: two rounds for 16 threads, 62 % of their time at best).
const CHUNK: usize = 128;

/// Neighbours per chunk of [`NeighbourLists::lanes`].
pub(crate) const LANES: usize = 8;

/// For each particle, the particles within h of it (itself excluded) when the
/// lists were built, in the grid's fixed query order: compressed rows, one
/// per particle.
///
/// ```
/// use sph_core::{NeighbourGrid, NeighbourLists, glam::Vec3};
/// let positions = [Vec3::ZERO, Vec3::new(0.5, 0.0, 0.0), Vec3::new(3.0, 0.0, 0.0)];
/// let grid = NeighbourGrid::build(&positions, 1.0).unwrap();
/// let lists = NeighbourLists::build(&grid).unwrap();
/// assert_eq!(lists.of(0), [1]);
/// assert_eq!(lists.of(2), [] as [u32; 0]);
/// assert_eq!(lists.pairs(), 2);
/// ```
#[derive(Debug, Clone, Default)]
pub struct NeighbourLists {
    /// Row `i` is `neighbours[start[i]..start[i + 1]]`.
    start: Vec<u32>,
    /// The rows, then [`LANES`] zeros when there is a particle, so that a
    /// row's last chunk of [`LANES`] can be read whole.
    neighbours: Vec<u32>,
    /// Each block's counts and rows while building, kept between builds.
    blocks: BuildMemory,
}

/// The blocks' buffers of the last build, kept for the next: fresh ones
/// every PBF substep cost page faults (22,398 against 1,983 in a run of
/// `pbf_stations`, and 0.87 against 0.49 ms for the lists at 10k
/// particles). They hold a second copy of the rows (4 bytes per pair); a
/// clone starts without them.
#[derive(Default)]
struct BuildMemory(Vec<(Vec<u32>, Vec<u32>)>);

impl Clone for BuildMemory {
    fn clone(&self) -> Self {
        Self::default()
    }
}

impl std::fmt::Debug for BuildMemory {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "BuildMemory({} blocks)", self.0.len())
    }
}

impl NeighbourLists {
    /// The lists of every particle of `grid`.
    ///
    /// # Errors
    /// [`Error::TooManyPairs`], as [`Self::rebuild`].
    pub fn build(grid: &NeighbourGrid) -> Result<Self> {
        let mut lists = Self::default();
        lists.rebuild(grid)?;
        Ok(lists)
    }

    /// Rebuilds the lists for `grid` in this memory.
    ///
    /// # Errors
    /// [`Error::TooManyPairs`] where the grid holds 2³² neighbour pairs or
    /// more (about 10⁸ particles at usual neighbour counts, 10⁶ at ten
    /// spacings' h): the lists' offsets are 32-bit. The lists are then
    /// empty.
    pub fn rebuild(&mut self, grid: &NeighbourGrid) -> Result<()> {
        let n = grid.len();
        // Room for as many neighbours per particle as last time and a few
        // more, so that a block's buffer rarely grows.
        let per_particle = self.pairs().div_ceil(self.len().max(1)) + 8;
        self.blocks
            .0
            .resize_with(n.div_ceil(CHUNK), Default::default);
        let blocks = Blocks::new(&mut self.blocks.0);
        let find = |range: Range<usize>, c: usize| {
            // SAFETY: each block fills its own buffers; nothing reads them
            // in this pass.
            let (counts, found) = unsafe { &mut blocks.block(c..c + 1)[0] };
            counts.clear();
            found.clear();
            found.reserve(range.len() * per_particle);
            let layout = &grid.layout;
            let [xs, ys, zs] = &layout.coords;
            let mut hits = scan::Hits::<{ scan::HIT_CAPACITY }>::new();
            for i in range {
                let before = found.len();
                let own = layout.rank[i];
                let n = grid.neighbourhood(i);
                let mut scan = scan::Scan::new(n.centre, grid.h2, [xs, ys, zs], &n.rows);
                while !scan.done() {
                    let count = scan.fill(&mut hits, 0);
                    let hit = &hits[..count];
                    if grid.by_slot {
                        // Slots are particles: copy the hits around the
                        // particle itself.
                        match hit.iter().position(|&k| k == own) {
                            Some(k) => {
                                found.extend_from_slice(&hit[..k]);
                                found.extend_from_slice(&hit[k + 1..]);
                            }
                            None => found.extend_from_slice(hit),
                        }
                    } else {
                        found.extend(
                            (hit.iter())
                                .filter(|&&k| k != own)
                                .map(|&k| layout.order[k as usize]),
                        );
                    }
                }
                counts.push((found.len() - before) as u32);
            }
        };
        region::run_by(n, CHUNK, &[&find]);
        let blocks = &self.blocks.0;
        // Where each block's rows begin: the pairs of the blocks before it.
        let mut bases = Vec::with_capacity(blocks.len());
        let mut total = 0u64;
        for (_, found) in blocks {
            bases.push(total);
            total += found.len() as u64;
        }
        if u32::try_from(total).is_err() {
            self.start.clear();
            self.start.push(0);
            self.neighbours.clear();
            return Err(Error::TooManyPairs { pairs: total });
        }
        // Each block's row ends and rows copied into place in parallel,
        // then the padding.
        let total = total as usize;
        let padding = if n > 0 { LANES } else { 0 };
        self.start.resize(n + 1, 0);
        self.start[0] = 0;
        self.neighbours.resize(total + padding, 0);
        self.neighbours[total..].fill(0);
        let (ends, out) = (
            Blocks::new(&mut self.start[1..]),
            Blocks::new(&mut self.neighbours[..total]),
        );
        let bases = &bases;
        let copy = |range: Range<usize>, c: usize| {
            let (counts, found) = &blocks[c];
            let base = bases[c] as usize;
            // SAFETY: block c's row ends and rows, disjoint from every
            // other block's; nothing reads them in this pass.
            let (ends, rows) = unsafe { (ends.block(range), out.block(base..base + found.len())) };
            let mut end = base as u32;
            for (e, &count) in ends.iter_mut().zip(counts) {
                end += count;
                *e = end;
            }
            rows.copy_from_slice(found);
        };
        region::run_by(n, CHUNK, &[&copy]);
        Ok(())
    }

    /// Sets `out[i] = f(i, neighbours of i, row i of pairs)` for every
    /// particle in parallel, where `pairs` holds one value per neighbour
    /// laid out as the rows are, row by row (see [`NeighbourLists::row`]): a pass that
    /// computes a value per particle and one per pair at once. The work is
    /// split in blocks of a fixed size, so the result does not depend on
    /// the number of threads.
    ///
    /// # Panics
    /// If `out` does not hold one value per particle or `pairs` one per
    /// neighbour pair.
    pub fn par_map_rows<T: Send, P: Send>(
        &self,
        out: &mut [T],
        pairs: &mut [P],
        f: impl Fn(usize, &[u32], &mut [P]) -> T + Sync,
    ) {
        let blocks = self.row_blocks(out, pairs);
        blocks
            .into_par_iter()
            .for_each(|(first, values, rows)| self.map_rows_of_block(first, values, rows, &f));
    }

    /// [`NeighbourLists::par_map_rows`] in a parallel region
    /// ([`crate::region::run`]): `f` must not use rayon.
    pub(crate) fn region_map_rows<T: Send + Sync, P: Send + Sync>(
        &self,
        out: &mut [T],
        pairs: &mut [P],
        f: impl Fn(usize, &[u32], &mut [P]) -> T + Sync,
    ) {
        let mut blocks = self.row_blocks(out, pairs);
        let blocks = Blocks::new(&mut blocks);
        let pass = |range: Range<usize>, c: usize| {
            // SAFETY: each block takes its own entry; nothing reads them.
            let (first, values, rows) = unsafe { &mut blocks.block(c..c + 1)[0] };
            debug_assert_eq!(*first, range.start);
            self.map_rows_of_block(*first, values, rows, &f);
        };
        region::run_by(self.len(), CHUNK, &[&pass]);
    }

    /// `out` and `pairs` cut into blocks of [`CHUNK`] particles and their
    /// rows: (first particle, values, rows).
    ///
    /// # Panics
    /// If `out` does not hold one value per particle or `pairs` one per
    /// neighbour pair.
    #[allow(clippy::type_complexity)]
    fn row_blocks<'a, T, P>(
        &self,
        out: &'a mut [T],
        pairs: &'a mut [P],
    ) -> Vec<(usize, &'a mut [T], &'a mut [P])> {
        assert_eq!(out.len(), self.len(), "one value per particle");
        assert_eq!(pairs.len(), self.pairs(), "one value per neighbour pair");
        let start = &self.start;
        let mut blocks = Vec::with_capacity(out.len().div_ceil(CHUNK));
        let mut rest = pairs;
        for (b, values) in out.chunks_mut(CHUNK).enumerate() {
            let first = b * CHUNK;
            let len = (start[first + values.len()] - start[first]) as usize;
            let (rows, tail) = std::mem::take(&mut rest).split_at_mut(len);
            rest = tail;
            blocks.push((first, values, rows));
        }
        blocks
    }

    /// `values[k] = f(i, neighbours of i, row i)` for the particles `i =
    /// first + k` of one block, whose rows are `rows`.
    fn map_rows_of_block<T, P>(
        &self,
        first: usize,
        values: &mut [T],
        rows: &mut [P],
        f: &impl Fn(usize, &[u32], &mut [P]) -> T,
    ) {
        let start = &self.start;
        let base = start[first];
        for (k, value) in values.iter_mut().enumerate() {
            let i = first + k;
            let row = (start[i] - base) as usize..(start[i + 1] - base) as usize;
            *value = f(i, self.of(i), &mut rows[row]);
        }
    }

    /// Particle `i`'s part of per-pair data laid out as the rows are (see
    /// [`NeighbourLists::par_map_rows`]).
    ///
    /// # Panics
    /// If `i >= self.len()` or `pairs` is shorter than the rows.
    #[inline]
    pub fn row<'p, P>(&self, i: usize, pairs: &'p [P]) -> &'p [P] {
        &pairs[self.start[i] as usize..self.start[i + 1] as usize]
    }

    /// Number of particles.
    pub fn len(&self) -> usize {
        self.start.len().saturating_sub(1)
    }

    /// Whether there are no particles.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The neighbours of particle `i`.
    ///
    /// # Panics
    /// If `i >= self.len()`.
    #[inline]
    pub fn of(&self, i: usize) -> &[u32] {
        &self.neighbours[self.start[i] as usize..self.start[i + 1] as usize]
    }

    /// Number of (ordered) neighbour pairs: the sum of every list's length.
    pub fn pairs(&self) -> usize {
        self.start.last().map_or(0, |&end| end as usize)
    }

    /// The neighbours of particle `i` in chunks of [`LANES`] indices: each
    /// chunk's place in the rows (where its per-pair data starts, see
    /// [`NeighbourLists::row`]), its indices, and how many of them are
    /// `i`'s (1 to [`LANES`]). The last chunk runs on into the next row or
    /// the padding, valid indices that a lane sum must weight by 0. Reading
    /// whole chunks spares the lane code a copy of variable length, which
    /// cost as much as the kernels.
    ///
    /// # Panics
    /// If `i >= self.len()`.
    #[inline(always)]
    pub(crate) fn lanes(&self, i: usize) -> impl Iterator<Item = (usize, &[u32; LANES], usize)> {
        let (lo, hi) = (self.start[i] as usize, self.start[i + 1] as usize);
        (lo..hi).step_by(LANES).map(move |at| {
            let chunk = self.neighbours[at..at + LANES].try_into();
            (at, chunk.expect("rows are padded"), (hi - at).min(LANES))
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    /// The lists are the brute-force neighbour sets in the grid's order, and
    /// `par_map_rows` hands each particle its own row of per-pair data.
    #[test]
    fn lists_match_brute_force_and_rows_line_up() {
        let positions: Vec<Vec3> = (0..2000)
            .map(|i| {
                let f = |k: u32| ((i * 7919 + k * 104_729) % 1000) as f32 / 1000.0;
                Vec3::new(f(1), f(2), f(3)) * 0.3
            })
            .collect();
        let h = 0.04;
        let grid = NeighbourGrid::build(&positions, h).unwrap();
        let lists = NeighbourLists::build(&grid).unwrap();
        assert_eq!(lists.len(), positions.len());
        for (i, &x) in positions.iter().enumerate() {
            let mut brute: Vec<u32> = (0..positions.len() as u32)
                .filter(|&j| {
                    j as usize != i && (x - positions[j as usize]).length_squared() <= h * h
                })
                .collect();
            let mut found = lists.of(i).to_vec();
            brute.sort_unstable();
            found.sort_unstable();
            assert_eq!(found, brute, "particle {i}");
        }
        // Each row's pair data is (i, j) of its own pairs.
        let mut pairs = vec![(0u32, 0u32); lists.pairs()];
        let mut counts = vec![0usize; lists.len()];
        lists.par_map_rows(&mut counts, &mut pairs, |i, list, row| {
            for (p, &j) in row.iter_mut().zip(list) {
                *p = (i as u32, j);
            }
            row.len()
        });
        for (i, &count) in counts.iter().enumerate() {
            assert_eq!(count, lists.of(i).len());
            let expected: Vec<_> = lists.of(i).iter().map(|&j| (i as u32, j)).collect();
            assert_eq!(lists.row(i, &pairs), expected);
        }
    }
}
