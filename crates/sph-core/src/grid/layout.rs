//! Building a grid's memory layout: particles sorted by cell into slots, the
//! occupied cells, and each cell's 9 neighbour rows.
//!
//! Two paths give the same layout. When the particles' cells fill their bounding
//! box densely (at most about two cells per particle, the usual case for a
//! fluid), cells are numbered densely in the box, x fastest, and one counting
//! pass sorts the particles: its prefix sums give every cell's first slot, so the
//! occupied cells and each cell's rows follow in O(1) per cell, and the scatter
//! writes the slot order, its inverse and the sorted coordinates in the same
//! pass. Sparse sets (a few particles far apart) sort (cell, index) keys by radix
//! or comparison instead and find rows by walking the sorted cells.

use glam::Vec3;
use rayon::prelude::*;

use super::{Cell, SlotRange, scan, zyx};
use crate::light::SERIAL_BELOW;
use crate::region::{self, Blocks};
use std::ops::Range;

/// The sorted particle data of a [`super::NeighbourGrid`]. Rebuilding from an
/// old layout refills its buffers instead of allocating new ones.
#[derive(Debug, Clone, Default)]
pub(super) struct Layout {
    /// Slot → input index.
    pub order: Vec<u32>,
    /// Input index → slot.
    pub rank: Vec<u32>,
    /// Slot → cell index.
    pub slot_cell: Vec<u32>,
    /// Occupied cells, sorted by (z, y, x).
    pub cells: Vec<Cell>,
    /// Slots of cell `c`: `cell_start[c]..cell_start[c + 1]`.
    pub cell_start: Vec<u32>,
    /// For each occupied cell, the 9 slot ranges covering its 27 neighbour cells.
    pub rows: Vec<[SlotRange; 9]>,
    /// x, y, z in slot order, each followed by [`scan::PADDING`] NaNs.
    pub coords: [Vec<f32>; 3],
    /// The box of a dense layout, whose prefix sums (`scratch.first`) give the
    /// rows around any cell; `None` for a sparse layout.
    dense: Option<Bounds>,
    /// Buffers of the dense sort kept for the next rebuild.
    scratch: Scratch,
}

/// The dense sort's buffers, refilled by the next rebuild.
#[derive(Debug, Clone, Default)]
struct Scratch {
    /// Dense cell number per input particle.
    keys: Vec<u32>,
    /// Per chunk of the input: count, then next slot, per dense cell.
    next: Vec<Vec<u32>>,
    /// First slot per dense cell, and n; point queries read it.
    first: Vec<u32>,
}

/// The bounding box of a set of cells.
#[derive(Debug, Clone, Copy)]
struct Bounds {
    lo: Cell,
    /// Cells along each axis.
    dims: [u64; 3],
}

impl Bounds {
    /// The box of the cells of points whose bounding box is `bounds` (none
    /// for no points), all in range. `cell` must be monotonic along each
    /// axis (a floor is).
    fn of(bounds: Option<(Vec3, Vec3)>, cell: impl Fn(Vec3) -> Cell) -> Option<Self> {
        let (lo, hi) = bounds?;
        let (lo, hi) = (cell(lo), cell(hi));
        let dims = [0, 1, 2].map(|a| (hi[a] as i64 - lo[a] as i64) as u64 + 1);
        Some(Self { lo, dims })
    }

    /// Position of `c` in the box along axis `a` (`c` inside the box).
    #[inline]
    fn rel(&self, c: Cell, a: usize) -> u64 {
        (c[a] as i64 - self.lo[a] as i64) as u64
    }

    /// Cells in the box, if that fits a `u64`.
    fn total(&self) -> Option<u64> {
        self.dims[0]
            .checked_mul(self.dims[1])
            .and_then(|v| v.checked_mul(self.dims[2]))
    }

    /// Dense number of a cell in the box: x fastest, so numbers increase in
    /// (z, y, x) order. Only for boxes whose [`Bounds::total`] is `Some`.
    #[inline]
    fn key(&self, c: Cell) -> u64 {
        self.rel(c, 0) + self.dims[0] * (self.rel(c, 1) + self.dims[1] * self.rel(c, 2))
    }

    /// The 9 rows around cell `c` (anywhere, occupied or not): the slots of
    /// (x − 1..=x + 1, y + dy, z + dz) clamped to the box, one contiguous range
    /// of dense numbers each, read from `first`, the first slot per dense cell.
    #[inline]
    fn rows(&self, first: &[u32], c: Cell) -> [SlotRange; 9] {
        let [nx, ny, nz] = self.dims.map(|d| d as i64);
        let rel = [0, 1, 2].map(|a| c[a] as i64 - self.lo[a] as i64);
        let (x0, x1) = ((rel[0] - 1).max(0), (rel[0] + 1).min(nx - 1));
        let mut rows = [SlotRange::default(); 9];
        if x0 > x1 {
            return rows;
        }
        let mut r = 0;
        for z in rel[2] - 1..=rel[2] + 1 {
            for y in rel[1] - 1..=rel[1] + 1 {
                if (0..ny).contains(&y) && (0..nz).contains(&z) {
                    let k = (x0 + nx * (y + ny * z)) as usize;
                    rows[r] = SlotRange {
                        start: first[k],
                        end: first[k + (x1 - x0) as usize + 1],
                    };
                }
                r += 1;
            }
        }
        rows
    }

    /// The cell with dense number `k`.
    #[inline]
    fn cell(&self, k: u64) -> Cell {
        let (x, yz) = (k % self.dims[0], k / self.dims[0]);
        let (y, z) = (yz % self.dims[1], yz / self.dims[1]);
        [
            (self.lo[0] as i64 + x as i64) as i32,
            (self.lo[1] as i64 + y as i64) as i32,
            (self.lo[2] as i64 + z as i64) as i32,
        ]
    }
}

impl Layout {
    /// The layout of particles at `positions` (finite, their cells in range),
    /// whose bounding box is `bounds` (`None` when there are none), `cell(p)`
    /// being the cell of position `p`.
    ///
    /// `reuse` is an old layout whose buffers are refilled (a default one for a
    /// first build).
    pub fn new(
        positions: &[Vec3],
        bounds: Option<(Vec3, Vec3)>,
        cell: impl Fn(Vec3) -> Cell + Sync,
        reuse: Self,
    ) -> Self {
        let Some(bounds) = Bounds::of(bounds, &cell) else {
            return Self::sparse(&[], positions, Vec::new());
        };
        let n = positions.len() as u64;
        match bounds.total() {
            Some(total) if total <= 2 * n + 1024 && total < u32::MAX as u64 => {
                reuse.dense(positions, cell, &bounds, total as usize)
            }
            Some(total) => {
                let cells: Vec<Cell> = positions.par_iter().map(|&p| cell(p)).collect();
                let keys: Vec<(u64, u32)> = cells
                    .par_iter()
                    .enumerate()
                    .map(|(i, &c)| (bounds.key(c), i as u32))
                    .collect();
                let order = radix_sort(keys, u64::BITS - (total - 1).leading_zeros());
                Self::sparse(&cells, positions, order)
            }
            None => {
                let cells: Vec<Cell> = positions.par_iter().map(|&p| cell(p)).collect();
                let mut pairs: Vec<(u128, u32)> = cells
                    .par_iter()
                    .enumerate()
                    .map(|(i, &c)| {
                        let r = |a| bounds.rel(c, a) as u128;
                        ((r(2) << 64) | (r(1) << 32) | r(0), i as u32)
                    })
                    .collect();
                // Pairs are unique (the index breaks ties): an unstable sort is
                // deterministic.
                pairs.par_sort_unstable();
                let order = pairs.into_par_iter().map(|(_, i)| i).collect();
                Self::sparse(&cells, positions, order)
            }
        }
    }

    /// Whether the layout is dense, so that [`Layout::dense_rows`] answers.
    pub fn is_dense(&self) -> bool {
        self.dense.is_some()
    }

    /// The 9 rows around cell `c` in O(1), for a dense layout; `None` for a
    /// sparse one (look the cells up instead).
    #[inline]
    pub fn dense_rows(&self, c: Cell) -> Option<[SlotRange; 9]> {
        Some(self.dense?.rows(&self.scratch.first, c))
    }

    /// Counting sort over the dense cell numbers of a densely occupied box.
    fn dense(
        self,
        positions: &[Vec3],
        cell: impl Fn(Vec3) -> Cell + Sync,
        bounds: &Bounds,
        total: usize,
    ) -> Self {
        let Self {
            mut order,
            mut rank,
            mut slot_cell,
            cells: occupied,
            cell_start,
            mut rows,
            mut coords,
            dense: _,
            scratch:
                Scratch {
                    mut keys,
                    mut next,
                    mut first,
                },
        } = self;
        let n = positions.len();
        // The build splits into parts (`build_parts`). Any split gives the
        // same layout: the sort is stable, each part scattering from the
        // slot where the parts before it ended.
        let parts = build_parts(n);
        let chunk_len = n.div_ceil(parts).max(1);
        let chunks = n.div_ceil(chunk_len);
        keys.clear();
        keys.resize(n, 0);
        next.resize_with(chunks, Vec::new);
        // Per chunk of the input: each particle's dense cell number, and a
        // histogram of them.
        {
            let (key_out, count_out) = (Blocks::new(&mut keys), Blocks::new(&mut next));
            let count = |range: Range<usize>, c: usize| {
                // SAFETY: chunk c writes its own keys and histogram alone.
                let (ks, counts) = unsafe {
                    (
                        key_out.block(range.clone()),
                        &mut count_out.block(c..c + 1)[0],
                    )
                };
                counts.clear();
                counts.resize(total, 0);
                for (k, &p) in ks.iter_mut().zip(&positions[range]) {
                    *k = bounds.key(cell(p)) as u32;
                    counts[*k as usize] += 1;
                }
            };
            region::run_by(n, chunk_len, &[&count]);
        }
        // Per range of dense cells: its particles and occupied cells, then
        // their running sums: where each range's slots and occupied cells
        // start.
        let range_len = total.div_ceil(parts).max(1);
        let ranges = total.div_ceil(range_len);
        let mut sums = vec![(0u32, 0u32); ranges];
        {
            let (out, counts) = (Blocks::new(&mut sums), &next);
            let sum = |range: Range<usize>, b: usize| {
                let (mut particles, mut occupied) = (0u32, 0u32);
                for k in range {
                    let here: u32 = counts.iter().map(|c| c[k]).sum();
                    particles += here;
                    occupied += u32::from(here > 0);
                }
                // SAFETY: range b writes its own sums alone.
                unsafe { out.block(b..b + 1)[0] = (particles, occupied) };
            };
            region::run_by(total, range_len, &[&sum]);
        }
        let mut bases = Vec::with_capacity(ranges);
        let (mut slots, mut cells) = (0u32, 0usize);
        for &(particles, occupied) in &sums {
            bases.push((slots, cells));
            slots += particles;
            cells += occupied as usize;
        }
        // first[k]: the first slot of dense cell k; first[total] = n. Each
        // chunk's count becomes its next slot in that cell; the occupied
        // cells and their first slots follow in cell order.
        first.clear();
        first.resize(total + 1, 0);
        first[total] = n as u32;
        let (mut occupied, mut cell_start) = (occupied, cell_start);
        occupied.clear();
        occupied.resize(cells, [0; 3]);
        cell_start.clear();
        cell_start.resize(cells + 1, 0);
        cell_start[cells] = n as u32;
        {
            let firsts = Blocks::new(&mut first[..total]);
            let (occupied_out, starts_out) = (
                Blocks::new(&mut occupied),
                Blocks::new(&mut cell_start[..cells]),
            );
            let counts: Vec<Scatter<u32>> =
                next.iter_mut().map(|c| Scatter(c.as_mut_ptr())).collect();
            let (bases, sums) = (&bases, &sums);
            let prefix = |range: Range<usize>, b: usize| {
                let (mut slot, o) = bases[b];
                let own = o..o + sums[b].1 as usize;
                // SAFETY: range b writes its own cells' firsts and counts,
                // and its own occupied cells, alone.
                let (first, occupied, starts) = unsafe {
                    (
                        firsts.block(range.clone()),
                        occupied_out.block(own.clone()),
                        starts_out.block(own),
                    )
                };
                let mut o = 0;
                for (f, k) in first.iter_mut().zip(range) {
                    *f = slot;
                    let start = slot;
                    for c in &counts {
                        // SAFETY: k < total, each chunk's histogram's
                        // length; only range b touches cell k.
                        unsafe {
                            let count = c.0.add(k);
                            (*count, slot) = (slot, slot + *count);
                        }
                    }
                    if slot > start {
                        (occupied[o], starts[o]) = (bounds.cell(k as u64), start);
                        o += 1;
                    }
                }
            };
            region::run_by(total, range_len, &[&prefix]);
        }

        // The scatter writes the slot order, its inverse and the sorted
        // coordinates in one pass. Every slot below n is written exactly once
        // (the per-chunk offsets partition 0..n), so the scatter targets are
        // not initialised first.
        rank.clear();
        rank.resize(n, 0);
        order.clear();
        order.reserve(n);
        for c in &mut coords {
            c.clear();
            c.reserve(n + scan::PADDING);
        }
        let [xs, ys, zs] = &mut coords;
        let out = (
            Scatter(order.as_mut_ptr()),
            Scatter(xs.as_mut_ptr()),
            Scatter(ys.as_mut_ptr()),
            Scatter(zs.as_mut_ptr()),
        );
        {
            let (rank_out, next_out, keys) =
                (Blocks::new(&mut rank), Blocks::new(&mut next), &keys);
            let scatter = |range: Range<usize>, c: usize| {
                let (order, xs, ys, zs) = out;
                // SAFETY: chunk c writes its own ranks and next slots alone.
                let (rank, next) = unsafe {
                    (
                        rank_out.block(range.clone()),
                        &mut next_out.block(c..c + 1)[0],
                    )
                };
                for (r, i) in rank.iter_mut().zip(range) {
                    let slot = &mut next[keys[i] as usize];
                    let s = *slot as usize;
                    *slot += 1;
                    *r = s as u32;
                    let p = positions[i];
                    // SAFETY: s < n <= capacity, and each slot is written by
                    // exactly one iteration of one chunk (see above).
                    unsafe {
                        order.write(s, i as u32);
                        xs.write(s, p.x);
                        ys.write(s, p.y);
                        zs.write(s, p.z);
                    }
                }
            };
            region::run_by(n, chunk_len, &[&scatter]);
        }
        // SAFETY: the scatter wrote every slot below n.
        unsafe { order.set_len(n) };
        for c in &mut coords {
            // SAFETY: as for `order`.
            unsafe { c.set_len(n) };
            c.extend([f32::NAN; scan::PADDING]);
        }

        rows.clear();
        rows.resize(cells, [SlotRange::default(); 9]);
        {
            let (out, occupied, first) = (Blocks::new(&mut rows), &occupied, &first);
            let each = |range: Range<usize>, _| {
                // SAFETY: each block writes its own cells' rows alone.
                let rows = unsafe { out.block(range.clone()) };
                for (r, &c) in rows.iter_mut().zip(&occupied[range]) {
                    *r = bounds.rows(first, c);
                }
            };
            region::run_by(cells, cells.div_ceil(parts).max(1), &[&each]);
        }
        fill_slot_cells(&cell_start, n, &mut slot_cell);
        Self {
            order,
            rank,
            slot_cell,
            cells: occupied,
            cell_start,
            rows,
            coords,
            dense: Some(*bounds),
            scratch: Scratch { keys, next, first },
        }
    }

    /// The layout for a given slot order (input indices sorted by (z, y, x) cell,
    /// ties by index).
    fn sparse(cells: &[Cell], positions: &[Vec3], order: Vec<u32>) -> Self {
        let n = cells.len();
        let mut rank = vec![0u32; n];
        for (s, &i) in order.iter().enumerate() {
            rank[i as usize] = s as u32;
        }
        let coords = [0, 1, 2].map(|a| padded_coordinate(&order, positions, a));
        // Cell boundaries in slot order.
        let cell_of_slot = |s: usize| cells[order[s] as usize];
        let mut cell_start: Vec<u32> = (0..n)
            .into_par_iter()
            .filter(|&s| s == 0 || cell_of_slot(s) != cell_of_slot(s - 1))
            .map(|s| s as u32)
            .collect();
        let occupied: Vec<Cell> = cell_start
            .par_iter()
            .map(|&s| cell_of_slot(s as usize))
            .collect();
        cell_start.push(n as u32);
        let rows = neighbour_rows(&occupied, &cell_start);
        let mut slot_cell = Vec::new();
        fill_slot_cells(&cell_start, n, &mut slot_cell);
        Self {
            slot_cell,
            order,
            rank,
            cells: occupied,
            cell_start,
            rows,
            coords,
            dense: None,
            scratch: Scratch::default(),
        }
    }
}

/// A vector's buffer written at disjoint indices from several threads.
#[derive(Clone, Copy)]
pub(super) struct Scatter<T>(pub(super) *mut T);

// SAFETY: `Scatter` is only a pointer; `write`'s contract (each index written by
// one thread only, in bounds) makes sharing it across threads sound.
unsafe impl<T: Send> Send for Scatter<T> {}
unsafe impl<T: Send> Sync for Scatter<T> {}

impl<T> Scatter<T> {
    /// # Safety
    /// `i` is in bounds of the buffer, and no other write or read of index `i`
    /// happens while the scatter runs.
    #[inline]
    pub(super) unsafe fn write(self, i: usize, value: T) {
        // SAFETY: upheld by the caller.
        unsafe { self.0.add(i).write(value) }
    }
}

/// Slot → cell index, from the cells' slot ranges, into `slot_cell`.
fn fill_slot_cells(cell_start: &[u32], n: usize, slot_cell: &mut Vec<u32>) {
    slot_cell.clear();
    slot_cell.reserve(n);
    let dst = Scatter(slot_cell.as_mut_ptr());
    let cells = cell_start.len() - 1;
    let each = |range: Range<usize>, _| {
        for c in range {
            for s in cell_start[c]..cell_start[c + 1] {
                // SAFETY: the cells' slot ranges partition 0..n (cell_start
                // rises from 0 to n) and n <= capacity, so each slot is
                // written once, by one thread.
                unsafe { dst.write(s as usize, c as u32) };
            }
        }
    };
    region::run_by(cells, cells.div_ceil(build_parts(n)).max(1), &[&each]);
    // SAFETY: every slot below n was written above.
    unsafe { slot_cell.set_len(n) };
}

/// How many parts a build over `n` particles splits into: as many as a
/// light pass takes ([`crate::light::parts`]), at most 8, and at most
/// [`TEAM_PARTS`] in a step's team below [`SERIAL_BELOW`].
fn build_parts(n: usize) -> usize {
    let cap = if n >= SERIAL_BELOW { 8 } else { TEAM_PARTS };
    crate::light::parts(n).min(cap)
}

/// The most parts a team's build below [`SERIAL_BELOW`] splits into. Each
/// part's histogram spans every dense cell, about two per particle in a
/// fluid, so clearing, summing and offsetting them costs every thread
/// about as many cells as there are whatever the split, against the
/// particles' n/parts: beyond a few parts the histograms outweigh the
/// split. Two parts took the 10k grid station from 0.59 to 0.42 ms
/// (`light`'s module docs); more were not measured (a 2-core VM).
const TEAM_PARTS: usize = 4;

/// Stable LSD radix sort of (key, index) pairs on the low `bits` bits of the key;
/// returns the indices. Input in index order, so ties stay in index order.
fn radix_sort(mut a: Vec<(u64, u32)>, bits: u32) -> Vec<u32> {
    let passes = bits.div_ceil(11);
    if passes > 0 {
        let digit = bits.div_ceil(passes);
        let mask = (1u64 << digit) - 1;
        let mut b = vec![(0u64, 0u32); a.len()];
        let mut counts = vec![0usize; 1 << digit];
        for pass in 0..passes {
            let shift = pass * digit;
            counts.fill(0);
            for &(k, _) in &a {
                counts[((k >> shift) & mask) as usize] += 1;
            }
            let mut sum = 0;
            for c in counts.iter_mut() {
                (*c, sum) = (sum, sum + *c);
            }
            for &e in &a {
                let d = ((e.0 >> shift) & mask) as usize;
                b[counts[d]] = e;
                counts[d] += 1;
            }
            std::mem::swap(&mut a, &mut b);
        }
    }
    a.into_par_iter().map(|(_, i)| i).collect()
}

/// For every occupied cell, the 9 slot ranges of its 27 neighbour cells.
///
/// For a fixed row offset (dy, dz), the target row (x−1..=x+1, y+dy, z+dz) moves
/// forward in (z, y, x) order as the cell does, so one forward walk over the sorted
/// cells finds every cell's row: O(cells) per offset with sequential memory access.
/// Chunks of cells walk in parallel, each starting from a binary search.
fn neighbour_rows(cells: &[Cell], cell_start: &[u32]) -> Vec<[SlotRange; 9]> {
    const CHUNK: usize = 4096;
    let mut rows = vec![[SlotRange::default(); 9]; cells.len()];
    rows.par_chunks_mut(CHUNK)
        .enumerate()
        .for_each(|(chunk, out)| {
            let first_cell = chunk * CHUNK;
            let mut r = 0;
            for dz in -1..=1 {
                for dy in -1..=1 {
                    let lo = |c: Cell| zyx([c[0] - 1, c[1] + dy, c[2] + dz]);
                    let hi = |c: Cell| zyx([c[0] + 1, c[1] + dy, c[2] + dz]);
                    let mut p = cells.partition_point(|&q| zyx(q) < lo(cells[first_cell]));
                    for (k, row) in out.iter_mut().enumerate() {
                        let cell = cells[first_cell + k];
                        while p < cells.len() && zyx(cells[p]) < lo(cell) {
                            p += 1;
                        }
                        let mut q = p;
                        while q < cells.len() && zyx(cells[q]) <= hi(cell) {
                            q += 1;
                        }
                        row[r] = SlotRange {
                            start: cell_start[p],
                            end: cell_start[q],
                        };
                    }
                    r += 1;
                }
            }
        });
    rows
}

/// One coordinate of the particles in slot order, followed by [`scan::PADDING`]
/// NaN entries that let the scan load whole chunks at the end of the last row
/// (NaN also fails every distance test).
fn padded_coordinate(order: &[u32], positions: &[Vec3], axis: usize) -> Vec<f32> {
    let mut out = Vec::with_capacity(order.len() + scan::PADDING);
    order
        .par_iter()
        .map(|&i| positions[i as usize][axis])
        .collect_into_vec(&mut out);
    out.extend([f32::NAN; scan::PADDING]);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The slots a row covers (empty rows compare equal whatever their start).
    fn slots(r: &SlotRange) -> std::ops::Range<u32> {
        if r.start < r.end {
            r.start..r.end
        } else {
            0..0
        }
    }

    /// The dense build gives the same layout in one part (outside a team)
    /// as in a team's three or four, built fresh or reusing the buffers of
    /// a layout of another split, at sizes below and above a part each.
    #[test]
    fn dense_builds_agree_for_any_split() {
        // A jittered lattice of n points with empty cells among them.
        let lattice = |n: usize| -> Vec<Vec3> {
            (0..n)
                .map(|i| {
                    let (x, y, z) = (i % 13, (i / 13) % 11, i / 143);
                    let j = ((i * 2_654_435_761) % 1000) as f32 / 1000.0;
                    Vec3::new(x as f32 * 1.7 + j, y as f32 * 0.9, z as f32 * 1.3 - j)
                })
                .collect()
        };
        let cell = |p: Vec3| p.floor().as_ivec3().to_array();
        let build = |x: &[Vec3], reuse: Layout| {
            let lo = x.iter().fold(Vec3::INFINITY, |a, &p| a.min(p));
            let hi = x.iter().fold(Vec3::NEG_INFINITY, |a, &p| a.max(p));
            Layout::new(x, Some((lo, hi)), cell, reuse)
        };
        let fields = |l: &Layout| {
            let rows: Vec<_> = l.rows.iter().map(|r| r.map(|r| slots(&r))).collect();
            let coords: Vec<Vec<u32>> = (l.coords.iter())
                .map(|c| c.iter().map(|v| v.to_bits()).collect())
                .collect();
            let first = l.scratch.first.clone();
            let cells = (l.cells.clone(), l.cell_start.clone(), l.slot_cell.clone());
            (l.order.clone(), l.rank.clone(), cells, rows, coords, first)
        };
        for n in [1, 5, 1001, 3000] {
            let x = lattice(n);
            // One part: outside a team, below `SERIAL_BELOW`.
            let one = build(&x, Layout::default());
            assert!(one.is_dense(), "{n}");
            for threads in [3, 7] {
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .unwrap();
                // In a team: 3 and 4 parts; then rebuilt from a layout of
                // another split, reusing its buffers.
                let (split, again) = pool.install(|| {
                    region::team(|| {
                        let split = build(&x, Layout::default());
                        let again = build(&x, build(&lattice(n / 2 + 1), Layout::default()));
                        (split, again)
                    })
                });
                assert!(
                    fields(&split) == fields(&one),
                    "{n} points, {threads} threads"
                );
                assert!(
                    fields(&again) == fields(&one),
                    "{n} points, {threads} threads, reused"
                );
            }
        }
    }

    /// The dense counting-sort path (scattered in parallel chunks) and the sparse
    /// radix path give the same layout on a set with empty cells, crowded cells
    /// and cells on the box's faces.
    #[test]
    fn dense_and_sparse_paths_agree() {
        let mut state = 0x2545_F491u32;
        let mut next = move |m: i32| {
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            (state % m as u32) as i32
        };
        let cells: Vec<Cell> = (0..100_000)
            .map(|_| {
                // The plane x = 0 stays empty.
                let x = next(7) - 3;
                [if x == 0 { 2 } else { x }, next(5) + 10, next(6) - 40]
            })
            .collect();
        let positions: Vec<Vec3> = cells
            .iter()
            .map(|c| Vec3::new(c[0] as f32, c[1] as f32, c[2] as f32) + 0.5)
            .collect();
        let cell = |p: Vec3| p.floor().as_ivec3().to_array();
        let lo = positions.iter().fold(Vec3::INFINITY, |a, &p| a.min(p));
        let hi = positions.iter().fold(Vec3::NEG_INFINITY, |a, &p| a.max(p));
        let bounds = Bounds::of(Some((lo, hi)), cell).unwrap();
        let total = bounds.total().unwrap();
        // Four threads: the scatter runs in four chunks (n ≥ 2¹⁵,
        // `crate::light::SERIAL_BELOW`).
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(4)
            .build()
            .unwrap();
        let dense =
            pool.install(|| Layout::default().dense(&positions, cell, &bounds, total as usize));
        let keys = cells
            .iter()
            .enumerate()
            .map(|(i, &c)| (bounds.key(c), i as u32))
            .collect();
        let order = radix_sort(keys, u64::BITS - (total - 1).leading_zeros());
        let sparse = Layout::sparse(&cells, &positions, order);
        assert_eq!(dense.order, sparse.order);
        assert_eq!(dense.rank, sparse.rank);
        assert_eq!(dense.slot_cell, sparse.slot_cell);
        assert_eq!(dense.cells, sparse.cells);
        assert_eq!(dense.cell_start, sparse.cell_start);
        for a in 0..3 {
            let (d, s) = (&dense.coords[a], &sparse.coords[a]);
            assert_eq!(d.len(), s.len());
            assert!(d.iter().zip(s).all(|(x, y)| x.to_bits() == y.to_bits()));
        }
        for (d, s) in dense.rows.iter().zip(&sparse.rows) {
            assert_eq!(d.map(|r| slots(&r)), s.map(|r| slots(&r)));
        }
        // Stable: ties in slot order keep input order.
        assert!(
            dense
                .order
                .windows(2)
                .all(|w| { cells[w[0] as usize] != cells[w[1] as usize] || w[0] < w[1] })
        );
    }
}
