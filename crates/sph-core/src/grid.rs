//! Neighbour search: a uniform grid of cell size h over an unbounded domain.
//!
//! # Layout
//!
//! [`NeighbourGrid::build`] computes each particle's integer cell, sorts the
//! particles by cell in (z, y, x) lexicographic order and stores their positions in
//! that order, struct-of-arrays, so a cell's particles are one contiguous *slot*
//! range. Only occupied cells are stored, so memory is O(particles) wherever the
//! particles are: a particle at 10⁷ m costs what one at the origin costs. Where
//! the cells fill their bounding box densely (a fluid), the counting sort's
//! prefix sums over the box find any cell's slots; for sparse sets a hash table
//! on the cell coordinates (as in Teschner et al. 2003 and the thesis, 3.3.1)
//! finds the occupied cells.
//!
//! Because cells are sorted with x fastest, the three cells (x−1, y, z), (x, y, z),
//! (x+1, y, z) are adjacent in slot order: the 27 cells around a cell are 9
//! contiguous slot ranges ("rows"), computed once per cell at build time. A query
//! scans those 9 ranges a chunk of candidates at a time (AVX-512, AVX2 or SSE2 on
//! x86-64, chosen at run time: [`crate::simd::simd_level`], see `scan.rs`).
//! The grid holds no physics: [`Neighbourhood::poly6_sums`], the colour
//! field's and WCSPH's density sums straight from the candidate rows, lives
//! with the kernels (`kernels/sums.rs`), the solvers' sums with the solvers.
//!
//! # Exactness
//!
//! A neighbour of `x` is every particle `j` with `|x − x_j|² ≤ h²`, evaluated in
//! `f32` as `dx·dx + dy·dy + dz·dz` with `d = x − x_j`, the same expression a brute
//! force loop uses, so the grid returns exactly the brute-force set. Cells are
//! computed in `f64` and are a relative 10⁻⁵ wider than h: rounding in the `f32`
//! distance can then never accept a pair two cells apart.
//!
//! # Determinism
//!
//! Slot order depends only on (cell, input index), and each query visits rows in a
//! fixed order and slots in increasing order, so every particle sees its neighbours
//! in the same order for any number of threads: sums over neighbours are bitwise
//! reproducible. [`Neighbourhood::poly6_sums`] is too, and every kind of its
//! lanes gives bitwise the same sums, so results do not depend on the CPU.

use std::borrow::Cow;

use glam::Vec3;
use rayon::prelude::*;

use crate::error::{Error, Result, check_h};

mod chunks;
mod layout;
mod lists;
mod scan;
pub use chunks::{CHUNK_LANES, Chunk, Chunks, reduce_halves, reduce_lanes};
pub use lists::NeighbourLists;
/// For tests elsewhere in the crate: the scan's hit buffer.
#[cfg(test)]
pub(crate) use scan::HIT_CAPACITY;
use scan::Scan;

/// The most particles a grid holds: slots are 32-bit, one value reserved.
pub const MAX_PARTICLES: usize = u32::MAX as usize - 1;

/// Cell edge relative to h: a little wider than h, see the module docs.
const CELL_SCALE: f64 = 1.0 + 1e-5;
/// Cell coordinates must satisfy |c| < 2³⁰, leaving room for ±1 neighbours and
/// key offsets in 32 bits.
const MAX_CELL: f64 = (1u64 << 30) as f64;

/// Integer cell coordinates (x, y, z).
type Cell = [i32; 3];

/// Marks a position whose cell is out of range (|c| < 2³⁰ for every real cell).
const BAD_CELL: Cell = [i32::MIN; 3];

/// The sort key of a cell: (z, y, x) lexicographic.
#[inline]
fn zyx(c: Cell) -> (i32, i32, i32) {
    (c[2], c[1], c[0])
}

/// A half-open range of slots.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub(crate) struct SlotRange {
    pub(crate) start: u32,
    pub(crate) end: u32,
}

/// A neighbour grid over a snapshot of particle positions.
///
/// Build it once per time step; query it for particles
/// ([`NeighbourGrid::for_each_neighbour`], [`NeighbourGrid::par_map`]) or for any
/// point in space ([`NeighbourGrid::for_each_neighbour_of_point`]).
///
/// ```
/// use sph_core::{NeighbourGrid, glam::Vec3};
/// let positions = [Vec3::ZERO, Vec3::new(0.5, 0.0, 0.0), Vec3::new(3.0, 0.0, 0.0)];
/// let grid = NeighbourGrid::build(&positions, 1.0).unwrap();
/// let mut found = Vec::new();
/// grid.for_each_neighbour(0, |j, _offset, _r2| found.push(j));
/// assert_eq!(found, [0, 1]); // itself and the particle 0.5 m away
/// ```
#[derive(Debug, Clone)]
pub struct NeighbourGrid {
    h: f32,
    h2: f32,
    inv_cell: f64,
    /// Particles sorted by cell, the occupied cells and their rows.
    layout: layout::Layout,
    /// Occupied cell → index in `layout.cells`, for queries at points in a
    /// sparse layout (empty for a dense one, whose prefix sums serve instead).
    table: CellTable,
    /// Whether particle k is slot k ([`NeighbourGrid::renumber_by_slot`]).
    by_slot: bool,
}

impl NeighbourGrid {
    /// Builds the grid for `positions` with search radius (and cell size) `h`, in
    /// parallel.
    ///
    /// Errors if `h` is not finite and positive, a position is NaN or infinite, a
    /// position is beyond 2³⁰·h from the origin, or there are more than
    /// [`MAX_PARTICLES`] (2³² − 2) particles.
    pub fn build(positions: &[Vec3], h: f32) -> Result<Self> {
        crate::light::released_if_heavy(positions.len(), || {
            Self::build_reusing(positions, h, layout::Layout::default(), Vec::new())
        })
    }

    /// Rebuilds the grid for new `positions` with the same h, reusing its memory:
    /// what a solver does every step. The result equals
    /// [`NeighbourGrid::build`]`(positions, self.h())`; on error (see `build`) the
    /// grid is left empty.
    pub fn rebuild(&mut self, positions: &[Vec3]) -> Result<()> {
        let h = self.h;
        let reuse = std::mem::take(&mut self.layout);
        let slots = std::mem::take(&mut self.table).into_slots();
        let built = crate::light::released_if_heavy(positions.len(), || {
            Self::build_reusing(positions, h, reuse, slots)
        });
        match built {
            Ok(grid) => {
                *self = grid;
                Ok(())
            }
            Err(e) => {
                *self = Self::build(&[], h)?;
                Err(e)
            }
        }
    }

    fn build_reusing(
        positions: &[Vec3],
        h: f32,
        reuse: layout::Layout,
        table_slots: Vec<u32>,
    ) -> Result<Self> {
        check_h(h)?;
        let n = positions.len();
        if n > MAX_PARTICLES {
            return Err(Error::TooManyParticles {
                count: n,
                limit: MAX_PARTICLES,
            });
        }
        let inv_cell = 1.0 / (h as f64 * CELL_SCALE);
        // One pass finds the bounding box and any non-finite coordinate; floor is
        // monotonic, so every cell is in range when the box's corners' are.
        let (lo, hi, finite) = (positions
            .par_iter()
            .with_min_len(crate::light::min_piece(n)))
        .map(|&p| (p, p, p.is_finite()))
        .reduce(
            || (Vec3::INFINITY, Vec3::NEG_INFINITY, true),
            |a, b| (a.0.min(b.0), a.1.max(b.1), a.2 && b.2),
        );
        let in_range =
            n == 0 || (cell_of(lo, inv_cell).is_some() && cell_of(hi, inv_cell).is_some());
        if !finite || !in_range {
            return Err(first_bad_position(positions, inv_cell, h));
        }
        let cell = |p: Vec3| cell_of(p, inv_cell).unwrap_or(BAD_CELL);

        let bounds = (n > 0).then_some((lo, hi));
        let layout = layout::Layout::new(positions, bounds, cell, reuse);
        let indexed: &[Cell] = if layout.is_dense() {
            &[]
        } else {
            &layout.cells
        };
        let table = CellTable::new(indexed, table_slots);
        Ok(Self {
            h,
            h2: h * h,
            inv_cell,
            layout,
            table,
            by_slot: false,
        })
    }

    /// The search radius h.
    #[inline]
    pub fn h(&self) -> f32 {
        self.h
    }

    /// Number of particles the grid was built over.
    #[inline]
    pub fn len(&self) -> usize {
        self.layout.order.len()
    }

    /// Whether the grid holds no particles.
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.layout.order.is_empty()
    }

    /// Number of occupied cells.
    #[inline]
    pub fn cell_count(&self) -> usize {
        self.layout.cells.len()
    }

    /// The particles in cell order: slot `k` holds input particle `order()[k]`.
    /// Passing it to [`crate::Particles::permute`] stores particles in the order
    /// the grid scans them, which makes gathers over neighbours cache-friendly.
    #[inline]
    pub fn order(&self) -> &[u32] {
        &self.layout.order
    }

    /// `values` (one per particle, by input index) in slot order, as
    /// [`Neighbourhood::poly6_sums`] takes its weights.
    ///
    /// After [`NeighbourGrid::renumber_by_slot`] (a solver's particles stored in
    /// grid order) they already are, and are borrowed, not copied.
    ///
    /// # Panics
    /// If `values.len() != self.len()`.
    pub fn to_slot_order<'v>(&self, values: &'v [f32]) -> Cow<'v, [f32]> {
        assert_eq!(values.len(), self.len(), "one value per particle");
        if self.by_slot {
            return Cow::Borrowed(values);
        }
        let order = &self.layout.order;
        let mut slots = vec![0.0; order.len()];
        crate::region::for_each(&mut slots, |s, v| *v = values[order[s] as usize]);
        Cow::Owned(slots)
    }

    /// Renumbers the grid's particles by slot, for use after the particle storage
    /// was reordered with `particles.permute(grid.order())`: particle `k` of the
    /// reordered storage is slot `k`, and queries and [`NeighbourGrid::par_map`]
    /// then walk memory in order. Only after that permutation: otherwise every
    /// index the grid reports names the wrong particle.
    pub fn renumber_by_slot(&mut self) {
        let n = self.len();
        let (orders, ranks) = (
            crate::region::Blocks::new(&mut self.layout.order),
            crate::region::Blocks::new(&mut self.layout.rank),
        );
        let identity = |range: std::ops::Range<usize>, _: usize| {
            // SAFETY: each block writes its own slots alone.
            let (order, rank) =
                unsafe { (orders.block(range.clone()), ranks.block(range.clone())) };
            for ((o, r), k) in order.iter_mut().zip(rank).zip(range) {
                (*o, *r) = (k as u32, k as u32);
            }
        };
        let block = n.div_ceil(crate::light::parts(n)).max(1);
        crate::region::run_by(n, block, &[&identity]);
        self.by_slot = true;
    }

    /// Calls `f(j, x_i − x_j, |x_i − x_j|²)` for every particle `j` within h of
    /// particle `i` (`i` itself included, first among its cell's particles by
    /// input index), in an order that does not depend on threads.
    ///
    /// # Panics
    /// If `i >= self.len()`, like slice indexing.
    #[inline]
    pub fn for_each_neighbour(&self, i: usize, f: impl FnMut(usize, Vec3, f32)) {
        self.neighbourhood(i).for_each(f);
    }

    /// The neighbourhood of particle `i`, to scan one or more times.
    ///
    /// # Panics
    /// If `i >= self.len()`, like slice indexing.
    #[inline]
    pub fn neighbourhood(&self, i: usize) -> Neighbourhood<'_> {
        self.neighbourhood_of_slot(self.layout.rank[i] as usize)
    }

    #[inline]
    fn neighbourhood_of_slot(&self, s: usize) -> Neighbourhood<'_> {
        let [xs, ys, zs] = &self.layout.coords;
        Neighbourhood {
            grid: self,
            centre: Vec3::new(xs[s], ys[s], zs[s]),
            rows: self.layout.rows[self.layout.slot_cell[s] as usize],
        }
    }

    /// The particles within h of an arbitrary point `x`. A point that is not finite
    /// or lies far outside the grid's range has no neighbours.
    pub fn neighbourhood_of_point(&self, x: Vec3) -> Neighbourhood<'_> {
        let rows = match point_cell(x, self.inv_cell) {
            Some(cell) if !self.is_empty() => self.layout.dense_rows(cell).unwrap_or_else(|| {
                point_rows(
                    cell,
                    &self.layout.cells,
                    &self.layout.cell_start,
                    &self.table,
                )
            }),
            _ => [SlotRange::default(); 9],
        };
        Neighbourhood {
            grid: self,
            centre: x,
            rows,
        }
    }

    /// Calls `f(j, x − x_j, |x − x_j|²)` for every particle `j` within h of the
    /// point `x`, in a fixed order. See [`NeighbourGrid::neighbourhood_of_point`].
    #[inline]
    pub fn for_each_neighbour_of_point(&self, x: Vec3, f: impl FnMut(usize, Vec3, f32)) {
        self.neighbourhood_of_point(x).for_each(f);
    }

    /// Evaluates `f(i, neighbourhood of i)` for every particle in parallel and
    /// returns the results indexed by particle. Work is scheduled in cell order (for
    /// locality); results are independent of the number of threads.
    pub fn par_map<T, F>(&self, f: F) -> Vec<T>
    where
        T: Copy + Send + Sync,
        F: Fn(usize, Neighbourhood<'_>) -> T + Sync,
    {
        let mut out = Vec::new();
        self.par_map_into(f, &mut out);
        out
    }

    /// [`NeighbourGrid::par_map`] into `out`, replacing its contents and reusing
    /// its memory: what a loop over frames does to avoid allocating per frame.
    ///
    /// On a thread that leads a [`crate::region::team`] it runs as one
    /// region pass on the team, so `f` must not use rayon there.
    pub fn par_map_into<T, F>(&self, f: F, out: &mut Vec<T>)
    where
        T: Copy + Send + Sync,
        F: Fn(usize, Neighbourhood<'_>) -> T + Sync,
    {
        let n = self.len();
        out.clear();
        out.reserve(n);
        let dst = layout::Scatter(out.as_mut_ptr());
        let one = |s: usize| {
            let i = self.layout.order[s] as usize;
            let value = f(i, self.neighbourhood_of_slot(s));
            // SAFETY: `order` is a permutation of 0..n, so every index below the
            // capacity n is written exactly once, by one thread.
            unsafe { dst.write(i, value) };
        };
        if crate::region::leading() {
            crate::region::run(
                n,
                &[&|slots: std::ops::Range<usize>, _| slots.for_each(one)],
            );
        } else {
            (0..n).into_par_iter().for_each(one);
        }
        // SAFETY: all n elements were initialised above (a panic in `f` propagates
        // before this line, leaving `out` empty).
        unsafe { out.set_len(n) };
    }
}

/// The particles within h of a centre point, as up to 9 contiguous slot ranges of a
/// [`NeighbourGrid`]. Cheap to copy; scanning it does not allocate.
#[derive(Debug, Clone, Copy)]
pub struct Neighbourhood<'a> {
    grid: &'a NeighbourGrid,
    centre: Vec3,
    rows: [SlotRange; 9],
}

impl Neighbourhood<'_> {
    /// The centre of the query.
    #[inline]
    pub fn centre(&self) -> Vec3 {
        self.centre
    }

    /// Calls `f(j, centre − x_j, |centre − x_j|²)` for every particle `j` with
    /// `|centre − x_j|² ≤ h²`, rows in a fixed order, slots increasing.
    #[inline]
    pub fn for_each(&self, mut f: impl FnMut(usize, Vec3, f32)) {
        let order = &self.grid.layout.order;
        self.for_each_slot(|k, d, r2| f(order[k] as usize, d, r2));
    }

    /// [`Neighbourhood::for_each`] with each neighbour's slot (its place in
    /// [`NeighbourGrid::order`]) instead of its index: per-particle data
    /// kept in slot order is read in the order it lies in memory.
    #[inline]
    pub fn for_each_slot(&self, mut f: impl FnMut(usize, Vec3, f32)) {
        let (g, c) = (&self.grid.layout, self.centre);
        let [xs, ys, zs] = &g.coords;
        let mut scan = Scan::new(c, self.grid.h2, [xs, ys, zs], &self.rows);
        let mut hits = scan::Hits::<{ scan::QUERY_CAPACITY }>::new();
        while !scan.done() {
            let n = scan.fill(&mut hits, 0);
            for &k in &hits[..n] {
                let k = k as usize;
                // The scan's arithmetic, so `r2` is the value it tested.
                let d = Vec3::new(c.x - xs[k], c.y - ys[k], c.z - zs[k]);
                f(k, d, d.x * d.x + d.y * d.y + d.z * d.z);
            }
        }
    }

    /// Number of particles within h of the centre.
    pub fn count(&self) -> usize {
        let mut n = 0;
        self.for_each(|_, _, _| n += 1);
        n
    }
}

/// The cell of a finite position in range, or `None`.
#[inline]
fn cell_of(p: Vec3, inv_cell: f64) -> Option<Cell> {
    let mut c = [0i32; 3];
    for a in 0..3 {
        let q = p[a] as f64 * inv_cell;
        // NaN and infinities fail this test too.
        if q.is_nan() || q.abs() >= MAX_CELL {
            return None;
        }
        c[a] = floor_i32(q);
    }
    Some(c)
}

/// `q.floor() as i32` for |q| < 2³¹ without a libm call (x86-64's baseline has no
/// rounding instruction): truncate, then step down where that rounded up.
#[inline]
fn floor_i32(q: f64) -> i32 {
    let t = q as i32;
    t - i32::from((t as f64) > q)
}

/// The cell of a query point, clamped: a point beyond the particles' range is put
/// in a cell at least two away from any particle's cell, so it finds nothing.
#[inline]
fn point_cell(p: Vec3, inv_cell: f64) -> Option<Cell> {
    if !p.is_finite() {
        return None;
    }
    let limit = MAX_CELL + 2.0;
    let mut c = [0i32; 3];
    for a in 0..3 {
        c[a] = floor_i32((p[a] as f64 * inv_cell).clamp(-limit, limit));
    }
    Some(c)
}

/// The error for the first position (by index) that [`cell_of`] rejects.
fn first_bad_position(positions: &[Vec3], inv_cell: f64, h: f32) -> Error {
    let index = positions
        .par_iter()
        .position_first(|&p| cell_of(p, inv_cell).is_none())
        .unwrap_or(0);
    let p = positions[index];
    if p.is_finite() {
        Error::OutOfGridRange {
            index,
            position: p.to_array(),
            h,
        }
    } else {
        Error::NonFinitePosition {
            index,
            position: p.to_array(),
        }
    }
}

/// The 9 rows around an arbitrary (possibly unoccupied) cell of a sparse layout.
fn point_rows(cell: Cell, cells: &[Cell], cell_start: &[u32], table: &CellTable) -> [SlotRange; 9] {
    let mut rows = [SlotRange::default(); 9];
    let mut r = 0;
    for dz in -1..=1 {
        for dy in -1..=1 {
            let centre = [
                cell[0],
                cell[1].saturating_add(dy),
                cell[2].saturating_add(dz),
            ];
            rows[r] = row_range(centre, cells, cell_start, table);
            r += 1;
        }
    }
    rows
}

/// The slots of the occupied cells among (x−1, y, z), (x, y, z), (x+1, y, z), which
/// are adjacent in the sorted cell list.
fn row_range(centre: Cell, cells: &[Cell], cell_start: &[u32], table: &CellTable) -> SlotRange {
    let left = [centre[0].saturating_sub(1), centre[1], centre[2]];
    let right = [centre[0].saturating_add(1), centre[1], centre[2]];
    let (first, last) = match table.find(centre, cells) {
        Some(k) => {
            let first = if k > 0 && cells[k - 1] == left {
                k - 1
            } else {
                k
            };
            let last = if k + 1 < cells.len() && cells[k + 1] == right {
                k + 1
            } else {
                k
            };
            (first, last)
        }
        None => match (table.find(left, cells), table.find(right, cells)) {
            (Some(a), Some(b)) => (a, b),
            (Some(a), None) => (a, a),
            (None, Some(b)) => (b, b),
            (None, None) => return SlotRange::default(),
        },
    };
    SlotRange {
        start: cell_start[first],
        end: cell_start[last + 1],
    }
}

/// Open-addressing hash table from cell coordinates to occupied-cell index.
#[derive(Debug, Clone, Default)]
struct CellTable {
    /// Cell index per slot, `EMPTY` where free.
    slots: Vec<u32>,
    shift: u32,
}

const EMPTY: u32 = u32::MAX;

impl CellTable {
    /// The table of `cells`, in the memory of `slots` (any content).
    fn new(cells: &[Cell], mut slots: Vec<u32>) -> Self {
        let capacity = (2 * cells.len()).next_power_of_two().max(16);
        slots.clear();
        slots.resize(capacity, EMPTY);
        let mut table = Self {
            slots,
            shift: 64 - capacity.trailing_zeros(),
        };
        let mask = capacity - 1;
        for (c, &cell) in cells.iter().enumerate() {
            let mut s = table.home(cell);
            while table.slots[s] != EMPTY {
                s = (s + 1) & mask;
            }
            table.slots[s] = c as u32;
        }
        table
    }

    /// Gives back the table's memory.
    fn into_slots(self) -> Vec<u32> {
        self.slots
    }

    /// Fibonacci hashing of the three coordinates (a variant of the large-prime XOR
    /// hash of Teschner et al. 2003 with better high bits).
    #[inline]
    fn home(&self, cell: Cell) -> usize {
        let h = (cell[0] as u32 as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
            ^ (cell[1] as u32 as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F)
            ^ (cell[2] as u32 as u64).wrapping_mul(0x1656_67B1_9E37_79F9);
        ((h ^ (h >> 31)).wrapping_mul(0x9E37_79B9_7F4A_7C15) >> self.shift) as usize
    }

    #[inline]
    fn find(&self, cell: Cell, cells: &[Cell]) -> Option<usize> {
        let mask = self.slots.len() - 1;
        let mut s = self.home(cell);
        loop {
            let c = self.slots[s];
            if c == EMPTY {
                return None;
            }
            if cells[c as usize] == cell {
                return Some(c as usize);
            }
            s = (s + 1) & mask;
        }
    }
}
